"""What ``srcsctl wait-ready`` counts as missing (SR-8.10), from ``status`` replies as the
daemon writes them; the waiting itself runs against the real daemon in
``tests/daemon/test_srcsctl.py``."""

from __future__ import annotations

from typing import Any

import pytest

from supervisord.api.readiness import BLOCKING_CAUSES, missing


def status(*active: str, phase: str = "passed", policy: str = "block") -> dict[str, Any]:
    """A ``status`` reply of a supervisor whose stop path works, but for ``active``."""
    return {
        "state": "STOPPED",
        "causes": [
            {"name": name, "active": True, "latched": True, "severity": "stop"} for name in active
        ],
        "prooftest": {"policy": policy, "phase": phase, "last": None},
        "daemon": {
            "link": {"open": True, "description": "serial /dev/srcs-vsc"},
            "outputs_not_acquired": [],
        },
    }


def test_a_working_stop_path_is_ready_whatever_the_state_and_the_stops() -> None:
    assert missing(status()) == []
    assert missing({**status(), "state": "RUN"}) == []
    # a pressed e-stop, a held client: the stop path working, not missing
    assert missing(status("vsc_estop", "client_hold:planner", "startup")) == []


@pytest.mark.parametrize("cause", [*sorted(BLOCKING_CAUSES), "output_fault:drive"])
def test_each_cause_that_breaks_the_stop_path_is_named(cause: str) -> None:
    assert missing(status(cause)) == [BLOCKING_CAUSES[cause.split(":", maxsplit=1)[0]]]
    latched_only = status(cause)
    latched_only["causes"][0]["active"] = False
    assert missing(latched_only) == []


@pytest.mark.parametrize("phase", ["waiting", "withholding", "resumed", "failed"])
def test_the_proof_test_must_have_passed(phase: str) -> None:
    assert missing(status(phase=phase)) == [
        f"the proof test of the VSC's watchdog has not passed ({phase})"
    ]


def test_a_config_without_a_proof_test_does_not_wait_for_one() -> None:
    assert missing(status(phase="off", policy="off")) == []


def test_a_closed_link_and_outputs_not_held_are_named() -> None:
    reply = status()
    reply["daemon"] = {
        "link": {"open": False, "description": "serial /dev/srcs-vsc"},
        "outputs_not_acquired": ["drive", "brake"],
    }
    assert missing(reply) == [
        "the link to the VSC is not open (serial /dev/srcs-vsc)",
        "outputs not held by the supervisor: drive, brake",
    ]

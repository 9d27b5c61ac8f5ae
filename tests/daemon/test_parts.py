"""The loop's parts built once from what the assembly hands over
(``supervisord/daemon/parts.py``), on a real serial link's path and sim outputs."""

from __future__ import annotations

from pathlib import Path

from supervisord.daemon.listener import Listener
from supervisord.daemon.loop import Supervisor
from supervisord.daemon.notify import Notifier
from supervisord.daemon.parts import Parts
from supervisord.links.serial_link import SerialLink
from supervisord.outputs import Output, create_output, parse_output_spec
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig


def _safety() -> SafetyConfig:
    return SafetyConfig(
        outputs=(
            OutputSpec("drive", OutputRole.MOTION),
            OutputSpec("brake", OutputRole.MOTION),
        )
    )


def _outputs() -> list[Output]:
    return [create_output(parse_output_spec(name, {"kind": "sim"})) for name in ("drive", "brake")]


def test_the_parts_are_built_from_what_is_handed_over_and_open_no_link_nor_output(
    tmp_path: Path,
) -> None:
    """SR-6: building opens no link and acquires no output (that is the start's, outputs
    first); each part that reads time is given the one clock (SR-2.11)."""
    link = SerialLink(str(tmp_path / "vsc"))

    def clock() -> int:
        return 42

    parts = Parts(_safety(), link, _outputs(), None, clock=clock)
    assert parts.link is link
    assert not link.is_open
    assert sorted(parts.outputs) == ["brake", "drive"]
    assert parts.clock is parts.port.clock is parts.bank.clock is clock
    assert parts.memory_locked is None
    assert not parts.stop.asked
    assert isinstance(parts.listener, Listener)  # a test's loop: an empty listener
    parts.waiter.close()  # its wake pair is made with it


def test_how_srcsctl_is_named_is_the_service_managers(tmp_path: Path) -> None:
    """SR-8.18: the name srcsd sets is the one the service manager's fixes say."""
    parts = Parts(_safety(), SerialLink(str(tmp_path / "vsc")), _outputs(), None)
    parts.srcsctl = "srcsctl --config /etc/srcs/robot.toml"
    assert parts.service.srcsctl == parts.srcsctl == "srcsctl --config /etc/srcs/robot.toml"
    parts.waiter.close()


def test_the_loop_holds_of_its_own_only_the_core_and_its_last_decision(tmp_path: Path) -> None:
    """The loop composes the parts; what is its own is what it decides with (docs/safety.md
    "The loop's parts")."""
    supervisor = Supervisor(_safety(), SerialLink(str(tmp_path / "vsc")), _outputs(), None)
    parts = Parts(_safety(), SerialLink(str(tmp_path / "vsc")), _outputs(), None)
    assert set(vars(supervisor)) == set(vars(parts))
    assert (supervisor.core, supervisor.decision) == (None, None)
    supervisor.waiter.close()
    parts.waiter.close()


def test_the_listener_the_notifier_and_the_release_handed_over_are_the_ones_used(
    tmp_path: Path,
) -> None:
    """srcsd's assembly hands over the API's listener, systemd's notifier (SR-0.2) and what
    the link must release (a CAN bus it owns, SR-6.6): each part holds the very one given,
    not an empty default in its place."""
    listener = Listener()
    notifier = Notifier({})
    released: list[str] = []

    def release() -> None:
        released.append("bus")

    parts = Parts(
        _safety(),
        SerialLink(str(tmp_path / "vsc")),
        _outputs(),
        None,
        listener=listener,
        notifier=notifier,
        release=[release],
    )
    assert parts.listener is listener
    assert parts.service.notifier is notifier
    assert parts.port.release == (release,)
    parts.waiter.close()

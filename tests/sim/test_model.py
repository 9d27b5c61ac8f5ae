"""The simulated VSC's state machine against the manual, on made-up monotonic times."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from supervisord.protocol.codes import MessageType, VscMode
from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackName,
    FeedbackSet,
    Gps,
    Joystick,
    MessageControl,
    RemoteStatus,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.protocol.nmea import parse_nmea
from supervisord.sim.model import (
    LINK_DELAY_S,
    Eeprom,
    EstopBit,
    Schedule,
    SimRefused,
    VscModel,
    gga_sentence,
)

T0 = 1000.0
LINKED = T0 + LINK_DELAY_S


def linked_model(**options: object) -> VscModel:
    model = VscModel(T0, **options)  # type: ignore[arg-type]
    assert model.mode(LINKED) in (VscMode.LOCAL, VscMode.REMOTE)
    return model


def operational() -> VscModel:
    model = linked_model()
    model.takeover(LINKED)
    return model


def heartbeats(messages: Sequence[object]) -> list[VscHeartbeat]:
    return [m for m in messages if isinstance(m, VscHeartbeat)]


def test_power_on_searches_with_the_remote_bits_then_links_in_local() -> None:
    """manual §6.1: Searching indicates an e-stop; §6.2: the first link gives Local, no e-stop."""
    model = VscModel(T0)
    first = heartbeats(model.tick(T0))[0]
    assert first.mode == VscMode.SEARCHING
    assert first.estop == EstopBit.REMOTE_LINK
    assert model.mode(LINKED) == VscMode.LOCAL
    assert model.estop_word(LINKED) == 0


def test_newer_firmware_reports_remote_where_older_reports_local() -> None:
    model = linked_model(newer_firmware=True)
    assert model.mode(LINKED) == VscMode.REMOTE
    model.takeover(LINKED)
    assert model.mode(LINKED) == VscMode.OPERATIONAL
    model.press_estop(LINKED + 1)
    assert model.mode(LINKED + 1) == VscMode.REMOTE


def test_local_leaves_only_by_takeover() -> None:
    """manual §6.2: "The only transition from Local mode is into Operational mode"."""
    model = linked_model()
    with pytest.raises(SimRefused, match="only from Operational"):
        model.pause(LINKED)
    model.takeover(LINKED)
    assert model.mode(LINKED) == VscMode.OPERATIONAL


def test_pause_and_takeover_from_pause() -> None:
    """manual §6.3 pause; §6.5 Operational is entered only from Local or Pause."""
    model = operational()
    model.pause(LINKED + 1)
    assert model.mode(LINKED + 1) == VscMode.PAUSE
    assert model.pause_reason == "button"
    model.takeover(LINKED + 2)
    assert model.mode(LINKED + 2) == VscMode.OPERATIONAL


def test_safetysense_pause_respects_its_enable_key() -> None:
    """Keys 82/83/84 switch the orientation, free-fall and inactivity pauses off."""
    model = operational()
    model.set_key(82, 0, LINKED)
    with pytest.raises(SimRefused, match="key 82"):
        model.pause(LINKED, "orientation")
    model.pause(LINKED, "free_fall")
    assert model.pause_reason == "free_fall"


def test_menu_entered_from_operational_returns_to_pause() -> None:
    """manual §6.4: Menu by its button; leaving does not resume motion without a takeover."""
    model = operational()
    model.menu(LINKED + 1)
    assert model.mode(LINKED + 1) == VscMode.MENU
    with pytest.raises(SimRefused, match="Local or Pause"):
        model.takeover(LINKED + 1)
    model.menu(LINKED + 2)
    assert model.mode(LINKED + 2) == VscMode.PAUSE


def test_sticks_and_buttons_are_zeroed_outside_operational() -> None:
    """Table 1: joysticks and buttons zeroed in every mode but Operational."""
    model = linked_model()
    model.set_axes({"left_x": 700, "right_z": -300}, LINKED)
    model.set_buttons({"up", "button_3"}, LINKED)
    assert model.joystick(LINKED) == Joystick()
    model.set_axes({"left_x": 0, "right_z": 0}, LINKED)
    model.takeover(LINKED)
    model.set_axes({"left_x": 700, "right_z": -300}, LINKED)
    live = model.joystick(LINKED)
    assert live.left_x.value == 700
    assert live.right_z.value == -300
    assert live.left_buttons.pressed == {"up"}
    assert live.right_buttons.pressed == {"button_3"}
    model.pause(LINKED + 1)
    assert model.joystick(LINKED + 1) == Joystick()
    assert all(axis.value == 0 for axis in model.joystick(LINKED + 1).axes)


def test_estop_returns_to_local_and_blocks_takeover_until_released() -> None:
    """manual §6.6: an e-stop always reverts to Local; enables return only once corrected."""
    model = operational()
    model.press_estop(LINKED + 1)
    beat = model.heartbeat(LINKED + 1)
    assert (beat.mode, beat.estop) == (VscMode.LOCAL, EstopBit.REMOTE_BUTTON)
    with pytest.raises(SimRefused, match="e-stop active"):
        model.takeover(LINKED + 1)
    model.release_estop(LINKED + 2)
    beat = model.heartbeat(LINKED + 2)
    assert (beat.mode, beat.estop) == (VscMode.LOCAL, 0)  # still Local: needs a takeover
    model.takeover(LINKED + 3)
    assert model.mode(LINKED + 3) == VscMode.OPERATIONAL


def test_wired_estop_and_user_request_are_stops_too() -> None:
    model = operational()
    model.set_wired_estop(True, LINKED + 1)
    assert model.heartbeat(LINKED + 1).estop == EstopBit.WIRED
    assert model.mode(LINKED + 1) == VscMode.LOCAL
    model.set_wired_estop(False, LINKED + 2)
    model.takeover(LINKED + 2)
    model.handle(UserHeartbeat(1), LINKED + 3)
    assert model.heartbeat(LINKED + 3) == VscHeartbeat(VscMode.LOCAL, 0, EstopBit.USER_REQUEST)
    model.handle(UserHeartbeat(0), LINKED + 4)
    assert model.estop_word(LINKED + 4) == 0


def test_takeover_refuses_deflected_sticks() -> None:
    model = linked_model()
    model.set_axes({"left_y": 10}, LINKED)
    with pytest.raises(SimRefused, match="neutral"):
        model.takeover(LINKED)
    assert model.mode(LINKED) == VscMode.LOCAL


def test_remote_off_is_searching_with_link_bits_and_relinks_in_local() -> None:
    model = operational()
    model.power(False, LINKED + 1)
    beat = model.heartbeat(LINKED + 1)
    assert (beat.mode, beat.estop) == (VscMode.SEARCHING, EstopBit.REMOTE_LINK)
    with pytest.raises(SimRefused, match="no link"):
        model.takeover(LINKED + 1)
    model.power(True, LINKED + 2)
    assert model.mode(LINKED + 2) == VscMode.SEARCHING  # the link takes link_delay
    assert model.mode(LINKED + 2 + LINK_DELAY_S) == VscMode.LOCAL


def test_remote_off_can_be_reported_as_local_with_the_remote_estop_bit() -> None:
    """PR-2.6: with ``remote_off_reports="local"`` a switched-off remote is reported as some
    hardware reports it, Local with the remote's e-stop bit 0x01, and sticks read neutral."""
    model = linked_model(remote_off_reports="local")
    model.takeover(LINKED)
    model.set_axes({"left_x": 300}, LINKED + 0.5)
    model.power(False, LINKED + 1)
    beat = model.heartbeat(LINKED + 1)
    assert (beat.mode, beat.estop) == (VscMode.LOCAL, EstopBit.REMOTE_BUTTON)
    assert model.joystick(LINKED + 1).left_x.value == 0
    with pytest.raises(SimRefused, match="no link"):
        model.takeover(LINKED + 1)
    model.power(True, LINKED + 2)
    assert model.heartbeat(LINKED + 2) == VscHeartbeat(VscMode.SEARCHING, 0, EstopBit.REMOTE_LINK)
    assert model.heartbeat(LINKED + 2 + LINK_DELAY_S) == VscHeartbeat(VscMode.LOCAL, 0, 0)


def test_key85_watchdog_trips_at_500_ms_inclusive() -> None:
    """manual §8.3.5, PR-2.8: with key 85 on, 500 ms without a user heartbeat raises the user
    e-stop. The simulator trips when the age reaches 0.5 s (inclusive)."""
    model = operational()
    model.set_key(85, 1, LINKED)
    model.handle(UserHeartbeat(0), 2000.0)
    model.takeover(2000.0)
    assert model.estop_word(2000.499) == 0
    assert model.mode(2000.499) == VscMode.OPERATIONAL
    assert model.estop_word(2000.5) == EstopBit.USER_TIMEOUT
    assert model.mode(2000.5) == VscMode.LOCAL
    model.handle(UserHeartbeat(0), 2000.6)  # heartbeats again: the bit clears, Local stays
    assert model.heartbeat(2000.6) == VscHeartbeat(VscMode.LOCAL, 0, 0)
    assert model.user_heartbeat_age(2000.7) == pytest.approx(0.1)


def test_key85_off_means_no_watchdog_and_never_on_can() -> None:
    model = operational()
    assert model.estop_word(LINKED + 60) == 0  # key 85 is off by default (table 13)
    can_model = VscModel(T0, transport="can")
    can_model.set_key(85, 1, T0)
    assert can_model.estop_word(T0 + 60) & EstopBit.USER_TIMEOUT == 0


def test_key85_watchdog_counts_from_boot_when_no_heartbeat_came() -> None:
    model = VscModel(
        T0,
        eeprom=Eeprom(
            dict(Eeprom.defaults("serial").message_control),
            {**Eeprom.defaults("serial").keys, 85: 1},
        ),
    )
    assert model.estop_word(T0 + 0.49) & EstopBit.USER_TIMEOUT == 0
    assert model.estop_word(T0 + 0.5) & EstopBit.USER_TIMEOUT


def test_default_rates_and_message_control() -> None:
    """Manual table 5, PR-2.10, PR-2.11: heartbeat 20 Hz, joystick 50 Hz, GPS ~1 Hz, remote status
    off. A message control changes a rate and is kept in the EEPROM (manual §8.3.6)."""
    model = operational()
    counts: dict[type, int] = {}
    start = 2000.0
    for step in range(1000):  # one second in 1 ms steps
        for message in model.tick(start + step / 1000):
            counts[type(message)] = counts.get(type(message), 0) + 1
    assert counts[VscHeartbeat] == 20
    assert counts[Joystick] == 50
    assert counts[Gps] == 1
    assert RemoteStatus not in counts
    version = model.eeprom_version
    model.handle(MessageControl(MessageType.REMOTE_STATUS, 1, 200), 3000.0)
    model.handle(MessageControl(MessageType.JOYSTICK, 1, 100), 3000.0)
    assert model.eeprom_version == version + 2
    assert model.eeprom.message_control[MessageType.REMOTE_STATUS] == Schedule(True, 200)
    counts = {}
    for step in range(1000):
        for message in model.tick(3000.0 + step / 1000):
            counts[type(message)] = counts.get(type(message), 0) + 1
    assert counts[RemoteStatus] == 5
    assert counts[Joystick] == 10


def test_message_control_below_20_ms_is_ignored() -> None:
    model = operational()
    model.handle(MessageControl(MessageType.JOYSTICK, 1, 19), LINKED)
    assert model.eeprom.message_control[MessageType.JOYSTICK] == Schedule(True, 20)
    assert model.ignored_messages == 1


def test_eeprom_round_trips_through_json_and_rejects_bad_files() -> None:
    model = operational()
    model.handle(MessageControl(MessageType.GPS, 0, 1000), LINKED)
    model.set_key(85, 1, LINKED)
    saved = model.consume_eeprom().to_json()
    again = Eeprom.from_json(saved, "serial")
    assert again.message_control[MessageType.GPS] == Schedule(False, 1000)
    assert again.keys[85] == 1
    with pytest.raises(ValueError, match="interval_ms"):
        Eeprom.from_json({"message_control": {"16": {"enabled": True, "interval_ms": 5}}}, "serial")
    with pytest.raises(ValueError, match="not a permanent key"):
        Eeprom.from_json({"keys": {"7": 1}}, "serial")


def test_feedback_get_answers_valid_keys_only() -> None:
    """manual §8.3.8, PR-2.8: a valid key is answered with a Feedback Set; an unknown one is not."""
    model = linked_model()
    model.handle(FeedbackGet(85), LINKED)
    model.handle(FeedbackGet(77), LINKED)
    model.handle(FeedbackSet(3, -42), LINKED)
    model.handle(FeedbackGet(3), LINKED)
    replies = [m for m in model.tick(LINKED) if isinstance(m, FeedbackSet)]
    assert replies == [FeedbackSet(85, 0), FeedbackSet(3, -42)]


def test_vibration_keys_count_and_run_750_ms() -> None:
    model = linked_model()
    model.handle(FeedbackSet(10, 1), LINKED)
    assert model.vibrating(LINKED + 0.7) == "left"
    assert model.vibrating(LINKED + 0.75) == ""
    model.handle(FeedbackSet(12, 1), LINKED + 1)
    model.handle(FeedbackSet(11, 0), LINKED + 1)  # only value 1 drives a motor
    assert model.vibration_count == 2


def test_menu_edit_is_sent_to_the_host() -> None:
    """manual §8.3.9: a value edited in the remote's menu comes back as a Feedback Set."""
    model = linked_model()
    with pytest.raises(SimRefused, match="Menu"):
        model.edit_value(2, 5, LINKED)
    model.menu(LINKED)
    model.edit_value(2, 5, LINKED)
    assert FeedbackSet(2, 5) in model.tick(LINKED)


def test_reboot_is_silent_then_a_fresh_start() -> None:
    """The bootloader's delay is silence and deafness, then Searching, then Local; the
    EEPROM survives, the host's heartbeat state does not."""
    model = operational()
    model.set_key(85, 1, LINKED)
    model.handle(UserHeartbeat(0), 2000.0)
    model.reboot(2000.0, 2.0)
    assert model.tick(2000.0) == []
    assert model.tick(2001.9) == []
    model.handle(FeedbackSet(1, 5), 2001.0)
    assert model.host_frames == 1  # the heartbeat before the reboot only
    beat = heartbeats(model.tick(2002.0))[0]
    assert beat.mode == VscMode.SEARCHING
    assert model.mode(2002.0 + LINK_DELAY_S) == VscMode.LOCAL
    assert model.eeprom.keys[85] == 1
    assert model.user_heartbeat_age(2002.0) is None


def test_inactivity_pause_then_auto_off() -> None:
    """manual §6.3/§6.4: (key 80 + 1) minutes without activity pauses; 2 minutes later the remote
    switches itself off when key 81 is on."""
    model = operational()
    model.set_key(80, 0, LINKED)
    assert model.mode(LINKED + 59.9) == VscMode.OPERATIONAL
    assert model.mode(LINKED + 60) == VscMode.PAUSE
    assert model.pause_reason == "inactivity"
    assert model.mode(LINKED + 60 + 119) == VscMode.PAUSE
    assert model.mode(LINKED + 60 + 120) == VscMode.SEARCHING
    assert not model.remote_on


def test_labels_and_display_mode_are_lost_on_relink() -> None:
    model = operational()
    model.handle(FeedbackName(90, "hello"), LINKED)
    model.handle(FeedbackSet(99, 1), LINKED)
    model.power(False, LINKED + 1)
    model.power(True, LINKED + 2)
    assert model.linked(LINKED + 2 + LINK_DELAY_S)
    assert model.labels == {}
    assert model.display_mode == 0


def test_rate_limits_are_counted() -> None:
    model = linked_model()
    for i in range(25):
        model.handle(FeedbackSet(1, i), LINKED + i * 0.01)  # 100 Hz: over the 20 Hz limit
    assert model.rate_violations > 0


def test_forced_mode_until_the_next_remote_action() -> None:
    model = linked_model()
    model.force_mode(0x42, LINKED)
    assert model.heartbeat(LINKED).mode == 0x42
    assert model.joystick(LINKED) == Joystick()
    model.press_estop(LINKED)
    assert model.heartbeat(LINKED).mode == VscMode.LOCAL


def test_generated_gps_reads_back() -> None:
    fix = parse_nmea(gga_sentence(3725.5, -33.8688, 151.2093))
    assert fix is not None
    assert fix.latitude == pytest.approx(-33.8688, abs=1e-4)
    assert fix.longitude == pytest.approx(151.2093, abs=1e-4)
    assert fix.utc_time is not None
    assert (fix.utc_time.hour, fix.utc_time.minute, fix.utc_time.second) == (13, 2, 5)


def test_lcd_rendering_follows_mode_and_display_mode() -> None:
    model = linked_model()
    assert "LOCAL" in model.render_lcd(LINKED)
    assert "Take over to drive" in model.render_lcd(LINKED)
    model.takeover(LINKED)
    screen = model.render_lcd(LINKED).splitlines()
    assert screen[0] == "+" + "-" * 20 + "+"
    assert all(len(line) == 22 for line in screen)
    assert screen[1].startswith("|OPERATIONAL")
    assert "LAT" in screen[3]
    model.handle(FeedbackSet(99, 1), LINKED)
    for key, text in zip(
        (90, 91, 92, 93), ("row one", "row two", "row three", "row four"), strict=True
    ):
        model.handle(FeedbackName(key, text), LINKED)
    assert model.render_lcd(LINKED).splitlines()[2:6] == [
        "|row one             |",
        "|row two             |",
        "|row three           |",
        "|row four            |",
    ]
    model.handle(FeedbackSet(99, 2), LINKED)
    model.handle(FeedbackName(1, "Speed"), LINKED)
    model.handle(FeedbackSet(1, 1234), LINKED)
    model.handle(FeedbackSet(2, 70000), LINKED)  # outside 16 bits: shown as XXXXXX
    rows = model.render_lcd(LINKED).splitlines()
    assert rows[2] == "|Speed           1234|"
    assert rows[3] == "|Value 2       XXXXXX|"
    model.handle(FeedbackSet(10, 1), LINKED)
    assert "<<" in model.render_lcd(LINKED).splitlines()[1]
    model.press_estop(LINKED + 1)
    estop_screen = model.render_lcd(LINKED + 1)
    assert "E-STOP" in estop_screen
    assert "Remote e-stop" in estop_screen
    model.power(False, LINKED + 2)
    assert "remote is off" in model.render_lcd(LINKED + 2)

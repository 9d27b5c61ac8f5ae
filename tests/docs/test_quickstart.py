"""The first-hour page (docs/quickstart.md) keeps its steps, in their order, each block
readable by the tiers that run it (SR-0.2).

The tiers run the page as written (tests/platforms/quickstart.py in a Debian root,
tests/system/guest/quickstart.py in the booted virtual machine); this is their fast half, on
every ``./dev test``: every step there and tagged for where it runs, every block valid bash,
and the page's commands, run against a model of what each needs and makes (the ordering
oracle below), reaching a guarded motion service, which the page without any one of its steps
does not."""

from __future__ import annotations

import re
import subprocess

import pytest

from tests.docs.quickstart import PAGE, STEPS, Block, PageError, blocks, script, without

# What a command needs and what it makes: (pattern, needs, makes, ends). A line no pattern
# takes is a command that needs nothing of the page (``srcsd --version``, ``getent``).
ORACLE: list[tuple[str, set[str], set[str], set[str]]] = [
    (r"^apt install -y \./srcs-supervisord_\*\.deb$", set(), {"package"}, set()),
    (r"^srcsd --version$", {"package"}, set(), set()),
    (r'^ls -lL "\$VSC"', {"vsc"}, {"seen: the device's group"}, set()),
    (r"^install -D .*/robot-motion\.conf /etc/sysusers\.d/", {"package"}, {"sysusers"}, set()),
    (r"^systemd-sysusers$", {"sysusers"}, {"user"}, set()),
    (r"^getent passwd robot-motion$", {"user"}, set(), set()),
    (r'^cat > "/etc/srcs/\$ROBOT\.toml" <<EOF$', {"package", "names"}, {"config"}, set()),
    (r"^srcsd --check-config ", {"config", "user"}, set(), set()),
    (r'^systemctl start "srcsd@\$ROBOT"$', {"config", "user"}, {"srcsd"}, set()),
    (r'^srcsctl -R "\$ROBOT" commission --yes$', {"srcsd", "vsc"}, {"commissioned"}, set()),
    (r'^srcsctl -R "\$ROBOT" wait-ready --timeout', {"srcsd", "commissioned"}, set(), set()),
    (r'^systemctl enable "srcsd@\$ROBOT"$', {"srcsd"}, {"enabled"}, set()),
    (r'^systemctl is-active "srcsd@\$ROBOT"$', {"srcsd"}, set(), set()),
    (r"^install -D .*/examples/robot_motion\.py /usr/local/lib/", {"package"}, {"program"}, set()),
    (r"^install -D .*/examples/robot-motion@\.service /etc/systemd/", {"package"}, {"unit"}, set()),
    (r"^systemctl daemon-reload$", {"unit"}, {"loaded"}, set()),
    (
        r'^systemctl enable --now "robot-motion@\$ROBOT"$',
        {"loaded", "program", "user", "srcsd", "commissioned"},
        {"motion"},
        set(),
    ),
    (r'^srcsctl -R "\$ROBOT" wait-ready --rearmable', {"motion", "commissioned"}, set(), set()),
    (r'^srcsctl -R "\$ROBOT" status$', {"srcsd"}, set(), set()),
    (r'^cat "/run/robot-motion/\$ROBOT/wheel"', {"run"}, {"seen: the wheel in RUN"}, set()),
    (r'^srcsctl -R "\$ROBOT" stoptest --yes$', {"run"}, {"stoptested"}, {"run"}),
    (r'^systemctl kill --signal=KILL "robot-motion@', {"motion", "run"}, {"lost"}, {"run"}),
    (r"^sleep \d+", set(), set(), set()),
    (r'^srcsctl -R "\$ROBOT" log --cause client_lost:motion', {"lost"}, set(), set()),
]
# What a hand step needs and makes, in the same terms.
HAND: dict[str, tuple[set[str], set[str]]] = {
    "names": (set(), {"names"}),
    "plug": ({"package"}, {"vsc"}),
    "takeover": ({"motion", "commissioned"}, {"run"}),
    "rearm": ({"stoptested"}, {"run"}),
    "again": ({"lost", "motion"}, {"run"}),
}
GOAL = {
    "enabled",
    "motion",
    "stoptested",
    "lost",
    "run",
    "seen: the device's group",
    "seen: the wheel in RUN",
}
"""The first hour's end: the supervisor enabled, the motion service up behind the gate, a
field stop test done, the motion service's death seen, and RUN again by a takeover; and the
two checks a team makes by eye on the way (the device's group, the wheel turning in RUN),
which no later command needs."""


def commands(block: Block) -> list[str]:
    """The block's commands: its lines without comments, a here-document's body skipped."""
    found: list[str] = []
    ending = None
    for raw in block.text.splitlines():
        if ending is not None:
            ending = None if raw == ending else ending
            continue
        line = re.sub(r"\s+#.*$", "", raw).strip()
        if not line or line.startswith("#"):
            continue
        found.append(line)
        heredoc = re.search(r"<<'?(\w+)'?$", line)
        ending = heredoc.group(1) if heredoc else None
    return found


def follow(page: str) -> set[str]:
    """The page's steps in order against the oracle: what the robot has at the end; an
    AssertionError at the first command or hand step whose needs are not met."""
    have: set[str] = set()
    for block in blocks(page):
        if block.by_hand:
            needs, makes = HAND[block.step]
            missing = needs - have
            assert not missing, f"by hand: {block.step} needs {sorted(missing)}"
            have |= makes
            continue
        for command in commands(block):
            rule = next((r for r in ORACLE if re.search(r[0], command)), None)
            assert rule is not None, f"{block.step}: no rule for {command!r}"
            _, needs, makes, ends = rule
            missing = needs - have
            assert not missing, f"{block.step}: {command!r} needs {sorted(missing)}"
            have = (have - ends) | makes
    return have


def test_the_page_has_every_step_in_order_tagged_where_it_runs() -> None:
    """SR-0.2: the package, the device, the users, the config, commissioning, the units, the
    motion service, the takeover, the stop test and the motion service's death, in this
    order, each run where STEPS says (a step run nowhere would not be tested)."""
    found = [(block.step, block.where) for block in blocks(PAGE.read_text())]
    assert found == list(STEPS)


def test_every_block_is_valid_bash_and_every_command_has_a_rule() -> None:
    """Each block parses (``bash -n``), and the oracle knows every command of it: a command
    added to the page without a rule fails here, so the oracle cannot fall behind."""
    for block in blocks(PAGE.read_text()):
        checked = subprocess.run(
            ["bash", "-n"], input=block.text, capture_output=True, text=True, check=False
        )
        assert checked.returncode == 0, f"{block.step} (line {block.line}): {checked.stderr}"
        if not block.by_hand:
            for command in commands(block):
                assert any(re.search(r[0], command) for r in ORACLE), command
    assert all(step in HAND for step, where in STEPS if where == "by hand")


def test_the_page_reaches_a_guarded_motion_service() -> None:
    """The page's commands in their order meet every need and end at the goal."""
    have = follow(PAGE.read_text())
    assert have >= GOAL, sorted(GOAL - have)


@pytest.mark.parametrize("step", [step for step, _ in STEPS])
def test_the_page_without_any_one_step_does_not(step: str) -> None:
    """Removed, each step leaves a later one without what it needs, or the end short of the
    goal: the oracle fails the page, as the tiers fail it when they run it."""
    mutated = without(PAGE.read_text(), step)
    with pytest.raises(AssertionError):
        assert follow(mutated) >= GOAL


def test_a_block_without_its_tag_is_refused_with_its_line() -> None:
    page = "text\n\n```sh\nsystemctl start srcsd@robot-a\n```\n"
    with pytest.raises(PageError, match="line 4: a ```sh block must start with '# test: "):
        blocks(page)
    with pytest.raises(PageError, match="places are root and guest"):
        blocks("```sh\n# test: install in laptop\ntrue\n```\n")


def test_the_script_runs_blocks_as_written_and_hand_steps_as_the_test_says() -> None:
    """The scripts the tiers run: a block's text unchanged, a hand step replaced, and the
    first failing command ending it, its step the last announced."""
    page = (
        "```sh\n# test: a by hand\n# do a\n```\n"
        "```sh\n# test: b in root\necho b-ran\n```\n"
        "```sh\n# test: c in guest\necho c-ran\n```\n"
        "```sh\n# test: d in root and guest\nfalse\necho d-after\n```\n"
    )
    text = script(page, "root", {"a": "echo a-by-test"})
    done = subprocess.run(["bash", "-c", text], capture_output=True, text=True, check=False)
    assert done.returncode == 1
    assert done.stdout.splitlines() == [
        "== a (by hand: the test)",
        "a-by-test",
        "== b",
        "b-ran",
        "== d",
    ]

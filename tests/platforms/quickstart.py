"""The first-hour page in a fresh Debian root, without systemd (docs/quickstart.md).

The page's blocks tagged ``root`` run as written, in order, in one shell inside a fresh
overlay of the cached base root (minbase and python3, ``roots.base``): the package installed
with apt from the directory that holds it, the VSC's device checked, the motion service's user
made by systemd-sysusers, the robot's config written and checked by ``srcsd --check-config``.
The page's hand steps are the test's (``HAND``): the names set (the VSC is a ``srcs-sim`` on a
pseudo-terminal), and the VSC plugged: ``srcs-sim`` started there and its pty given to
``srcs-dev`` as the package's udev rule gives the USB port. The blocks tagged ``guest`` need a
running systemd: the system tier runs them (tests/system/guest/quickstart.py).

Then the same page without its ``users`` step, in another fresh overlay: it must fail, at the
config's check, naming the missing user (tests/docs/quickstart.py ``without``): the tier shows
on every run that a step missing from the page fails it.

usage: python3 -m tests.platforms.quickstart SUITE DEB
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import time
from pathlib import Path

from tests.docs.quickstart import PAGE, last_step, script, without
from tests.platforms.report import Report, tail
from tests.platforms.roots import CACHE, RootError, base, enter, scratch, week

ARCH = "amd64"
HAND = {
    "names": "\n".join(
        (
            "ROBOT=robot-a",
            "VSC=/run/quickstart/vsc",
            "CHIP=gpiochip0",
            "LINE=17",
            "mkdir -p /run/quickstart",
        )
    ),
    # The VSC plugged: srcs-sim on a pty at $VSC, given to srcs-dev, mode 0660, as the rule
    # (units/60-srcs.rules) gives the USB port. It ends with the root's PID namespace.
    "plug": "\n".join(
        (
            'srcs-sim --serial "$VSC" --control /run/quickstart/sim.sock'
            " >/run/quickstart/sim.log 2>&1 &",
            'for _ in $(seq 300); do [ -e "$VSC" ] && break; sleep 0.1; done',
            'chgrp srcs-dev "$(readlink -f "$VSC")"',
            'chmod 0660 "$(readlink -f "$VSC")"',
        )
    ),
}


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: python3 -m tests.platforms.quickstart SUITE DEB", file=sys.stderr)
        return 2
    suite, deb_arg = argv
    deb = Path(deb_arg).resolve()
    report = Report(f"quickstart {suite}")
    try:
        root = base(suite, ARCH)
    except RootError as error:
        report.fail(f"a {suite} {ARCH} root", str(error))
        return report.end()
    work = scratch(f"quickstart-{suite}")
    # The one package file alone in its directory: the page installs ./srcs-supervisord_*.deb.
    debs = work / "debs"
    debs.mkdir()
    shutil.copy2(deb, debs / deb.name)
    archives = CACHE / "apt" / f"{suite}-{ARCH}-{week()}"
    archives.mkdir(parents=True, exist_ok=True)
    page = PAGE.read_text()

    def inside(text: str, overlay: str) -> tuple[int, str, float]:
        started = time.monotonic()
        result = enter(
            ["bash", "-c", "cd /srv/debs\n" + text],
            layers=[root],
            work=work / overlay,
            binds=[(debs, "/srv/debs:ro"), (archives, "/var/cache/apt/archives")],
            timeout=600,
        )
        return result.returncode, result.stdout + result.stderr, time.monotonic() - started

    code, output, took = inside(script(page, "root", HAND), "page")
    report.say(f"time the page's root blocks: {took:.0f} s")
    if report.check(
        code == 0 and last_step(output) == "done",
        "the page's root blocks, as written, in a fresh root",
        f"stopped at step {last_step(output)!r}:{tail(output, 40)}",
    ):
        report.check("robot-a.toml: OK" in output, "srcsd --check-config says OK", tail(output, 10))
        report.check(
            "crw-rw---- 1 root srcs-dev" in output,
            "the VSC's device: group srcs-dev, mode 0660",
            tail(output, 40),
        )

    code, output, took = inside(script(without(page, "users"), "root", HAND), "without-users")
    report.say(f"time the page without its users step: {took:.0f} s")
    report.check(
        code != 0
        and last_step(output) == "config"
        and 'user = "robot-motion": no such user' in output,
        "the page without its users step fails at the config's check, naming the user",
        f"exit {code}, stopped at {last_step(output)!r}:{tail(output, 20)}",
    )
    return report.end()


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except subprocess.TimeoutExpired as error:
        print(f"quickstart: FAILED a step took too long: {error}", flush=True)
        sys.exit(1)

"""The Debian package in a Debian root: install, run, one stop end to end, remove, purge.

In a fresh copy of a cached base root (``roots.base``: minbase and python3) of the suite and
architecture given, as docs/install.md tells an administrator:

1. ``apt-get install -y ./srcs-supervisord_VERSION_ARCH.deb``: apt fetches systemd from the
   registry (not udev, which the package only recommends: the roots install no recommended
   package); postinst runs ``systemd-sysusers`` and ``systemd-tmpfiles`` in the
   root (no systemd runs there; its ``systemctl`` and ``udevadm`` calls are skipped as in an
   image build). ``policy-rc.d`` keeps every service down. Checked: the package installed,
   ``srcsd --version``, the users and groups, the directories and their owners, the fleet
   stop's agent (its user ``srcs-fleet``, ``srcs-fleet-agent --version``, its MQTT client
   paho-mqtt imported by the root's own Python, no instance enabled: a fleet turns it on),
   ``import gpiod`` in the package's environment (its one compiled module used by srcsd),
   and ``srcsd --check-config --portable`` of every example config the package ships
   (``/usr/share/doc/srcs-supervisord/examples/*.toml``: their clients' user ``robot`` is the
   administrator's to create, so this root lacks it, a warning with ``--portable``).
2. ``estop.py`` (beside this file) with the package's ``/opt/srcsd/bin/python3``, inside a
   network namespace of its own (loopback only): ``srcs-sim`` and ``srcsd`` from the package,
   a takeover, the remote's e-stop, ``srcsctl status`` and ``srcsctl log``.
   Then ``container.py`` (beside this file), the same way: docs/containers.md's recipe as the
   package installs the page, srcsd without systemd as PID 1 of a PID namespace (SR-0.4);
   natively only (``RECIPE_NATIVE_ONLY``).
3. ``apt-get remove``: the program is gone, the stop record, the config and the users stay
   (SR-7.4). ``apt-get purge``: nothing the package installed remains, nor the record, the
   users and groups (``srcs-fleet`` too); the administrator's config in ``/etc/srcs`` stays.

A root whose ``python3`` the package's ``Depends`` exclude (none of bookworm's, trixie's or
unstable's today: the package carries its compiled modules for each of their Pythons) is a
different scenario: apt must refuse the package, naming python3, and install nothing.

usage: python3 -m tests.platforms.package SUITE ARCH DEB
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from tests.platforms.report import Report, tail
from tests.platforms.roots import CACHE, HERE, RootError, base, enter, run, scratch, week

PACKAGE = "srcs-supervisord"
EXAMPLES = f"/usr/share/doc/{PACKAGE}/examples"
SLOW = {"amd64": 1.0, "arm64": 20.0}
"""How much longer every deadline is: arm64 runs under qemu-user (docs/platforms.md)."""

APT = r"""
# Install with the lists the root came with; a mirror of unstable may have dropped a
# version since: then fetch the lists again and retry once.
apt_get() {
    apt-get "$@" >/tmp/apt.log 2>&1 && { cat /tmp/apt.log; return 0; }
    if grep -q 'Failed to fetch\|Unable to fetch' /tmp/apt.log; then
        apt-get update -qq && apt-get "$@"
        return
    fi
    cat /tmp/apt.log
    return 1
}
"""

INSTALL = (
    APT
    + r"""
apt_get install -y -q "/srv/debs/$DEB" || exit 1
echo "== status"; dpkg-query -W -f '${Status} ${Version}\n' srcs-supervisord
echo "== said"; grep '^srcs-supervisord: ' /tmp/apt.log || true
echo "== version"; srcsd --version
echo "== users"; getent passwd srcsd | cut -d: -f1,7
for group in srcsd srcs-dev srcs-admin srcs-operator; do getent group "$group" | cut -d: -f1; done
echo "== fleet agent"
getent passwd srcs-fleet | cut -d: -f1,7
srcs-fleet-agent --version
/opt/srcsd/bin/python3 -c 'import paho.mqtt.client, supervisord.fleet_agent.mqtt_edge as edge
print("paho", paho.mqtt.__version__)'
ls /etc/systemd/system/*.wants/ 2>/dev/null | grep -c '^srcs-fleet-agent@' || true
echo "== dirs"; stat -c '%n %U:%G %a' /etc/srcs /var/lib/srcsd /var/log/srcsd
echo "== gpiod"
/opt/srcsd/bin/python3 -c 'import gpiod, sys; print(gpiod.__version__, sys.version.split()[0])'
echo "== files"; dpkg -L srcs-supervisord >/srv/job/files
echo "== examples"
for config in EXAMPLES/*.toml; do
    if srcsd --check-config --portable "$config" >/tmp/check.log 2>&1; then
        echo "passed $config"
        grep ': warning: ' /tmp/check.log | sed 's/^/warned /' || true
    else
        echo "failed $config: $(tr '\n' ' ' </tmp/check.log)"
    fi
done
""".replace("EXAMPLES", EXAMPLES)
)

REMOVE = r"""
apt-get remove -y -q srcs-supervisord >/tmp/apt.log 2>&1 || { cat /tmp/apt.log; exit 1; }
echo "== status"; dpkg-query -W -f '${Status}\n' srcs-supervisord || true
echo "== left"
for path in /opt/srcsd /usr/sbin/srcsd /usr/bin/srcsctl /var/lib/srcsd/platform/stops.jsonl \
    /etc/srcs/platform.toml; do
    [ -e "$path" ] && echo "exists $path" || echo "absent $path"
done
getent passwd srcsd >/dev/null && echo "user srcsd" || echo "no user srcsd"
"""

PURGE = r"""
apt-get purge -y -q srcs-supervisord >/tmp/apt.log 2>&1 || { cat /tmp/apt.log; exit 1; }
echo "== said"; grep '^srcs-supervisord: ' /tmp/apt.log || true
echo "== status"; dpkg-query -W -f '${Status}\n' srcs-supervisord 2>&1 || true
echo "== left"
while read -r path; do
    [ -d "$path" ] && [ ! -L "$path" ] && continue   # shared directories (/usr/bin, ...)
    { [ -e "$path" ] || [ -L "$path" ]; } && echo "file $path"
done </srv/job/files
for path in /opt/srcsd /usr/share/doc/srcs-supervisord /var/lib/srcsd /var/log/srcsd; do
    [ -e "$path" ] && echo "file $path"
done
for name in srcsd srcs-fleet srcs-dev srcs-admin srcs-operator; do
    getent group "$name" >/dev/null && echo "group $name"
done
getent passwd srcsd >/dev/null && echo "user srcsd"
getent passwd srcs-fleet >/dev/null && echo "user srcs-fleet"
echo "== etc"; ls -A /etc/srcs 2>/dev/null || echo "(no /etc/srcs)"
true
"""


def sections(output: str) -> dict[str, list[str]]:
    """The ``== NAME`` parts of a script's output."""
    parts: dict[str, list[str]] = {"": []}
    current = ""
    for line in output.splitlines():
        if line.startswith("== "):
            current = line[3:].strip()
            parts[current] = []
        else:
            parts[current].append(line)
    return parts


def deb_field(deb: Path, field: str) -> str:
    return run(["dpkg-deb", "-f", deb, field], timeout=60).stdout.strip()


def root_python(root: Path) -> str:
    """The version of the root's python3 package, from its dpkg database."""
    status = (root / "var/lib/dpkg/status").read_text()
    for stanza in status.split("\n\n"):
        if stanza.startswith("Package: python3\n"):
            for line in stanza.splitlines():
                if line.startswith("Version: "):
                    return line.split(": ", 1)[1]
    return ""


def admits(depends: str, python: str) -> bool:
    """Whether ``python3 VERSION`` meets every ``python3 (OP V)`` of ``depends``."""
    operators = {">=": "ge", "<<": "lt", "<=": "le", ">>": "gt", "=": "eq"}
    for clause in depends.split(","):
        words = clause.replace("(", " ").replace(")", " ").split()
        if len(words) == 3 and words[0] == "python3":
            relation = operators[words[1]]
            compared = run(["dpkg", "--compare-versions", python, relation, words[2]], timeout=30)
            if compared.returncode != 0:
                return False
    return True


RECIPE_NATIVE_ONLY = (
    "its commands are the same on every architecture, and its real-time CPU budget, 1 s "
    "without blocking, is spent by Python's start-up under emulation: the SIGXCPU left the "
    "emulated srcsd hung in qemu-user"
)


def container(report: Report, inside: Callable[..., tuple[int, str, float]]) -> None:
    """docs/containers.md's recipe as written: srcsd without systemd, PID 1 of its own PID
    namespace (SR-0.4)."""
    recipe = "/opt/srcsd/bin/python3 /srv/platforms/container.py"
    code, output, took = inside(recipe, net=True, limit=300)
    report.say(f"time container recipe: {took:.0f} s")
    relay(report, output, "container recipe: ")
    report.check(code == 0, "container.py exits 0", tail(output, 40))


def relay(report: Report, output: str, what: str) -> None:
    """A script's ``time:`` and ``check:`` lines (estop.py's, container.py's) as the report's."""
    for line in output.splitlines():
        if line.startswith("time: "):
            report.say("time " + line[6:] + " s")
        elif line.startswith("check: ok "):
            report.check(True, what + line[10:])
        elif line.startswith("check: FAILED "):
            report.check(False, what + line[14:])


def main(argv: list[str]) -> int:
    if len(argv) != 3:
        print("usage: python3 -m tests.platforms.package SUITE ARCH DEB", file=sys.stderr)
        return 2
    suite, arch, deb_arg = argv
    deb = Path(deb_arg).resolve()
    report = Report(f"package {suite} {arch}")
    slow = SLOW.get(arch, 1.0)
    try:
        root = base(suite, arch)
    except RootError as error:
        report.fail(f"a {suite} {arch} root", str(error))
        return report.end()
    work = scratch(f"package-{suite}-{arch}")
    share = work / "share"  # /srv/job in the root: the package's file list, between steps
    share.mkdir()
    archives = CACHE / "apt" / f"{suite}-{arch}-{week()}"
    archives.mkdir(parents=True, exist_ok=True)
    binds = [
        (deb.parent, "/srv/debs:ro"),
        (HERE, "/srv/platforms:ro"),
        (share, "/srv/job"),
        # Fetched packages are kept for the week: a warm run installs without downloading.
        (archives, "/var/cache/apt/archives"),
    ]

    def inside(script: str, *, net: bool = False, limit: float) -> tuple[int, str, float]:
        started = time.monotonic()
        result = enter(
            ["sh", "-c", script],
            layers=[root],
            work=work / "overlay",
            binds=binds,
            net=net,
            env={"DEB": deb.name, "SRCS_PLATFORM_ROOT": "1"},
            timeout=limit,
        )
        return result.returncode, result.stdout + result.stderr, time.monotonic() - started

    version = deb_field(deb, "Version")
    depends = deb_field(deb, "Depends")
    python = root_python(root)
    report.say(f"{deb.name} (Depends: {depends}) on {suite} {arch} with python3 {python}")

    code, output, took = inside(INSTALL, limit=900 * max(1.0, slow / 4))
    report.say(f"time apt-get install: {took:.0f} s")
    if not admits(depends, python):
        # The package says it cannot run on this Python: apt must refuse it, install nothing.
        report.say(
            f"the package's Depends exclude python3 {python}: apt must refuse it (the full "
            "scenario runs once the package admits this Python)"
        )
        report.check(
            code != 0 and "python3" in output and "unmet dependencies" in output.lower(),
            "apt-get install refuses it, naming python3",
            tail(output),
        )
        report.check(
            not (work / "overlay/upper/opt/srcsd").exists(), "nothing installed in /opt/srcsd"
        )
        return report.end()
    parts = sections(output)
    if not report.check(code == 0, "apt-get install -y ./" + deb.name, tail(output)):
        return report.end()
    report.check(
        parts["status"] == [f"install ok installed {version}"], "dpkg: installed", parts["status"]
    )
    report.check(
        parts["said"]
        == ["srcs-supervisord: installed; nothing runs until a robot is configured. Next:"],
        "the first install says what to do next",
        parts["said"],
    )
    report.check(
        any(version in line for line in parts["version"]),
        f"srcsd --version names {version}",
        parts["version"],
    )
    report.check(
        parts["users"]
        == ["srcsd:/usr/sbin/nologin", "srcsd", "srcs-dev", "srcs-admin", "srcs-operator"],
        "sysusers: user srcsd (nologin), groups srcsd, srcs-dev, srcs-admin, srcs-operator",
        parts["users"],
    )
    report.check(
        parts["fleet agent"]
        == [
            "srcs-fleet:/usr/sbin/nologin",
            f"srcs-fleet-agent {version}",
            "paho 2.1.0",
            "0",
        ],
        "the fleet agent: its user (nologin), --version, paho-mqtt imported by the root's "
        "Python, no instance enabled",
        parts["fleet agent"],
    )
    report.check(
        parts["dirs"]
        == [
            "/etc/srcs root:root 755",
            "/var/lib/srcsd srcsd:srcsd 750",
            "/var/log/srcsd srcsd:srcsd 750",
        ],
        "tmpfiles: /etc/srcs, /var/lib/srcsd, /var/log/srcsd with their owners and modes",
        parts["dirs"],
    )
    report.check(
        len(parts["gpiod"]) == 1 and parts["gpiod"][0][:1].isdigit(),
        "import gpiod with /opt/srcsd/bin/python3",
        parts["gpiod"],
    )
    report.say(f"gpiod, python: {' '.join(parts['gpiod'])}")
    examples = parts["examples"]
    report.check(bool(examples), f"example configs in {EXAMPLES}", "none found")
    for line in examples:
        if line.startswith("warned "):
            # The examples bind their clients to the user robot, which the administrator
            # creates (docs/configuration.md "Checking a config"): that warning alone is
            # expected in a fresh root, where the package's groups exist.
            report.check(
                'user = "robot": no such user on this machine' in line,
                "only the clients' user robot missing",
                line,
            )
            continue
        report.check(line.startswith("passed "), "srcsd --check-config " + line.split()[1], line)

    estop = f"/opt/srcsd/bin/python3 /srv/platforms/estop.py --slow {slow}"
    code, output, took = inside(estop, net=True, limit=300 * slow)
    report.say(f"time end to end: {took:.0f} s")
    relay(report, output, "stop end to end: ")
    report.check(code == 0, "estop.py exits 0", tail(output, 40))

    if slow == 1.0:
        container(report, inside)
    else:
        report.say(f"container recipe: not under qemu-user ({RECIPE_NATIVE_ONLY})")

    code, output, took = inside(REMOVE, limit=300 * max(1.0, slow / 4))
    report.say(f"time apt-get remove: {took:.0f} s")
    parts = sections(output)
    if report.check(code == 0, "apt-get remove", tail(output)):
        report.check(
            parts["status"] == ["deinstall ok config-files"],
            "dpkg: removed, its purge still to come",
            parts["status"],
        )
        report.check(
            parts["left"]
            == [
                "absent /opt/srcsd",
                "absent /usr/sbin/srcsd",
                "absent /usr/bin/srcsctl",
                "exists /var/lib/srcsd/platform/stops.jsonl",
                "exists /etc/srcs/platform.toml",
                "user srcsd",
            ],
            "remove: the program gone; the stop record, the config and the user kept",
            parts["left"],
        )

    code, output, took = inside(PURGE, limit=300 * max(1.0, slow / 4))
    report.say(f"time apt-get purge: {took:.0f} s")
    parts = sections(output)
    if report.check(code == 0, "apt-get purge", tail(output)):
        report.check(
            not any(line.startswith("srcs-supervisord") for line in parts["status"])
            or "not-installed" in " ".join(parts["status"]),
            "dpkg: purged",
            parts["status"],
        )
        report.check(
            len(parts["said"]) == 2
            and parts["said"][0].startswith("srcs-supervisord: purge deletes the stop record")
            and parts["said"][1].startswith("srcs-supervisord: kept /etc/srcs:"),
            "purge says that it deletes the stop record and keeps /etc/srcs",
            parts["said"],
        )
        report.check(
            parts["left"] == [],
            "purge: no file, user or group of the package remains, nor the stop record",
            parts["left"],
        )
        report.check(
            parts["etc"] == ["platform.toml"],
            "purge: /etc/srcs kept, holding only the administrator's config",
            parts["etc"],
        )
    return report.end()


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except subprocess.TimeoutExpired as error:
        print(f"package: FAILED a step took too long: {error}", flush=True)
        sys.exit(1)

"""The test suite under another Python: pytest inside a Debian 13 (3.13) or unstable (3.14) root.

The root's own interpreter runs it (``python3 -m venv``, Debian's ``python3-venv``), with the
test dependencies from PyPI at the versions and hashes of ``requirements/build.txt`` and
``requirements/dev.txt`` (the same files ``./dev test`` installs from), and the Debian
packages the tests call (the list below, as ``./dev`` installs them on the host). That
environment is a cached layer over the base root (``roots.layer``), remade when a lock file,
``pyproject.toml`` or this recipe changes. Each run copies the tracked files of this tree to
``/src`` in a fresh upper layer and runs pytest there, inside a network namespace of its own
(loopback only; the test run's own namespace rule, docs/testing.md "Network", finds it
private already).

What runs, what is left out and why (docs/platforms.md "The test suite under 3.13 and 3.14"):
every test but those of ``LEFT_OUT``, with the fault suite (``tests/faults``, more than
half of the suite's time) split by file between the two roots (``FAULTS``), so that each
root's run stays near five minutes on two cores and every fault scenario runs under one of
the two Pythons. A fault file in neither list runs in both.

usage: python3 -m tests.platforms.suite SUITE [PYTEST ARGS...]
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from tests.platforms.report import Report, tail
from tests.platforms.roots import REPO, RootError, base, enter, host_ca, layer, run, scratch

LEFT_OUT = {
    "tests/ros2": "rclpy and the ROS 2 message wheels (requirements/ros2.txt) exist for 3.11/3.12",
    "tests/packaging": "builds and lints the .deb on the host; package.py runs it in each root",
    "tests/bench": "the benches' smoke tests time the host; benches run on real hardware",
    "tests/test_citations.py": "lists the tree with git ls-files; the copy in a root has no .git",
    # A loop device: the root's private /dev has none (the host's is never bound in).
    "tests/faults/test_record_faults.py::"
    "test_a_slow_disk_delays_records_never_the_stop_and_loses_none": "mounts a loop device",
    "tests/record/test_stop_views.py::test_the_picture_of_every_stop_kind_in_a_browser": (
        "Chromium, a Debian package of some hundred MB per root, renders the same SVG under any"
        " Python; the host's run renders it, the roots' runs check the picture's text"
    ),
    "tests/faults/test_flight.py::"
    "test_a_hung_disk_under_the_windows_never_delays_the_outputs_or_a_record": (
        "mounts a loop device"
    ),
}
FAULTS = {
    "trixie": [
        "test_serial_line.py",
        "test_serial_device.py",
        "test_signals.py",
        "test_host.py",
        "test_record_faults.py",
        "test_hung_userdb.py",
        "test_docs.py",
    ],
    "sid": [
        "test_slots.py",
        "test_prooftest.py",
        "test_can.py",
        "test_clients.py",
        "test_takeover.py",
        "test_odd_input.py",
        "test_flood.py",
        "test_budget.py",
        "test_remote.py",
        "test_flight.py",
    ],
}
"""The fault suite's files, by the root that runs them (about 140 s each, measured)."""
DEBIAN = (
    # ./dev's list for the tests (TEST_PACKAGES): venv, the fault suite's socat, faketime and ip,
    # man and bash-completion for the generated pages, prometheus for the exporter's scrape,
    # systemd-journal-remote for srcsctl fleet's collector.
    "python3-venv socat faketime iproute2 man-db bash-completion prometheus "
    "systemd-journal-remote "
    # On the host these come with Debian 12's standard system: journald and systemd-analyze
    # (tests/journald.py, the unit checks), mkfs.ext4 and fsfreeze (the record on a frozen
    # disk), setpriv and unshare (the odd-user and hung-userdb scenarios), ps and kill.
    "systemd e2fsprogs util-linux procps "
    # nsswitch.conf's passwd asking systemd, as on Debian 12's standard system (the hung
    # user-database scenario, tests/faults/test_hung_userdb.py).
    "libnss-systemd"
)
RECIPE = f"""
apt-get install -y -q {DEBIAN} >/tmp/apt.log 2>&1 || {{ tail -n 30 /tmp/apt.log; exit 1; }}
command -v setpriv >/dev/null || apt-get install -y -q setpriv >/dev/null
apt-get clean
mkdir -p /src/supervisord
cp /srv/repo/pyproject.toml /srv/repo/README.md /src/
cp -r /srv/repo/supervisord/. /src/supervisord/
python3 -m venv /src/.venv
/src/.venv/bin/pip install -q --disable-pip-version-check --no-cache-dir --require-hashes \\
    -r /srv/repo/requirements/build.txt
/src/.venv/bin/pip install -q --disable-pip-version-check --no-cache-dir --no-build-isolation \\
    --require-hashes -r /srv/repo/requirements/dev.txt
/src/.venv/bin/pip install -q --disable-pip-version-check --no-cache-dir --no-build-isolation \\
    --no-deps -e /src
rm -rf /src/supervisord /src/pyproject.toml /src/README.md
"""
CA = "/etc/ssl/srcs-platforms-host-ca.crt"
"""Where the host's certificate authorities are bound while pip runs (``roots.host_ca``)."""
RUN = """
cd /src
.venv/bin/python --version
exec .venv/bin/python -m pytest -p no:cacheprovider -q --durations=0 "$@"
"""


def tracked_files() -> list[str]:
    result = run(["git", "-C", REPO, "ls-files", "-z"], timeout=60)
    if result.returncode != 0:
        raise RootError(f"git ls-files: {result.stderr}")
    return [name for name in result.stdout.split("\0") if name]


def copy_tree(target: Path) -> int:
    """This tree's tracked files (as they are now) into ``target``; how many."""
    names = tracked_files()
    for name in names:
        source = REPO / name
        if not source.is_file():
            continue  # deleted in the working tree
        destination = target / name
        destination.parent.mkdir(parents=True, exist_ok=True)
        destination.write_bytes(source.read_bytes())
        destination.chmod(source.stat().st_mode & 0o777)
    return len(names)


def summary(output: str) -> str:
    """pytest's closing line (``N passed, N failed in S``)."""
    for line in reversed(output.splitlines()):
        if " in " in line and ("passed" in line or "failed" in line or "error" in line):
            return line.strip("= ")
    return ""


def main(argv: list[str]) -> int:
    if not argv:
        print(
            "usage: python3 -m tests.platforms.suite SUITE [--without-faults | PYTEST ARGS...]",
            file=sys.stderr,
        )
        return 2
    suite, *pytest_args = argv
    report = Report(f"suite {suite}")
    key = [
        (REPO / name).read_bytes()
        for name in ("requirements/build.txt", "requirements/dev.txt", "pyproject.toml")
    ]
    started = time.monotonic()
    try:
        root = base(suite, "amd64")
        deps = layer(
            [root],
            "suite",
            RECIPE,
            key=key,
            binds=[(REPO, "/srv/repo:ro"), (host_ca(), f"{CA}:ro")],
            env={"PIP_CERT": CA},
            timeout=1800,
        )
    except (RootError, subprocess.TimeoutExpired) as error:
        report.fail(f"a {suite} root with the test dependencies", str(error))
        return report.end()
    report.took("root and test dependencies", started)
    work = scratch(f"suite-{suite}")
    copied = copy_tree(work / "upper/src")
    report.say(f"{copied} tracked files copied to /src")
    without_faults = pytest_args == ["--without-faults"]
    if not pytest_args or without_faults:
        pytest_args = [
            f"--{'deselect' if '::' in path else 'ignore'}={path}" for path in sorted(LEFT_OUT)
        ]
        for path, why in sorted(LEFT_OUT.items()):
            report.say(f"left out {path}: {why}")
        if without_faults:
            pytest_args.append("--ignore=tests/faults")
            report.say("left out tests/faults: --without-faults (CI's run, docs/platforms.md)")
        else:
            elsewhere = [n for other, names in FAULTS.items() if other != suite for n in names]
            pytest_args += [f"--ignore=tests/faults/{name}" for name in elsewhere]
            report.say(f"the fault suite's files run by another root: {' '.join(elsewhere)}")
    started = time.monotonic()
    try:
        result = enter(
            ["sh", "-c", RUN, "run", *pytest_args],
            layers=[deps, root],
            work=work,
            net=True,
            env={"PYTHONDONTWRITEBYTECODE": "1"},
            timeout=1500,
        )
    except subprocess.TimeoutExpired:
        report.fail("pytest finished within 25 minutes")
        return report.end()
    report.took("pytest", started)
    output = result.stdout + result.stderr
    (work / "pytest.log").write_text(output)
    interpreter = result.stdout.splitlines()[0] if result.stdout else "?"
    report.say(f"{interpreter}; the whole output: {work / 'pytest.log'}")
    for line in output.splitlines():
        if line.startswith(("FAILED ", "ERROR ", "SKIPPED ")):
            report.say(line)
    closing = summary(output)
    report.say(f"pytest: {closing}")
    report.check(result.returncode == 0, f"pytest passes under {suite}'s python3", tail(output, 40))
    return report.end()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

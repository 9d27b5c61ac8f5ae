"""The Debian package that ``./dev deb`` builds (packaging/build_deb.py, docs/install.md): its
files where Debian puts them (SR-0.2: the units, users, directories and udev rule that put the
supervisor in its place), no compiler or -dev dependency, maintainer scripts that parse and
never delete the stop record on a plain remove (SR-7.4), launchers that run from an unpacked
tree, every Python from 3.10 to 3.14, lintian's approval, a copyright file that covers every
bundled distribution, no path of the build machine, and the same bytes from two builds. Built
once per session, and once more to compare; nothing is ever installed on this machine (the
system tier installs it in its guest, docs/system-tier.md)."""

from __future__ import annotations

import gzip
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from supervisord.config import toml
from tests.packaging import build_script

ROOT = Path(__file__).resolve().parents[2]
LAUNCHERS = ("srcsd", "srcsctl", "srcs-sim", "srcs-exporter", "srcs-fleet-agent")
PYTHONS = ("3.10", "3.11", "3.12", "3.13", "3.14")
SITE = "opt/srcsd/lib/python3/site-packages"
DOC = "usr/share/doc/srcs-supervisord"
SOMEONE_ELSE = "someone.else@build.invalid"
"""DEBEMAIL while the package is built: the Maintainer field must not take it."""


def _version() -> str:
    with (ROOT / "pyproject.toml").open("rb") as handle:
        return str(toml.load(handle)["project"]["version"])


def _packaged_env() -> dict[str, str]:
    """The environment without the developer's PYTHON* settings (PYTHONPATH names this tree):
    the packaged programs must find everything in their own tree, as on a robot."""
    return {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}


def _build(out: Path) -> Path:
    """packaging/build_deb.py into ``out/dist``, working in ``out/work``, as ./dev deb runs it."""
    env = {**_packaged_env(), "DEBEMAIL": SOMEONE_ELSE, "DEBFULLNAME": "Someone Else"}
    result = subprocess.run(
        [
            sys.executable,
            "packaging/build_deb.py",
            *("--out", str(out / "dist"), "--work", str(out / "work")),
        ],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    return Path(result.stdout.strip())


@pytest.fixture(scope="session")
def deb(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The package built from this tree, once per session, in a directory of the session's own."""
    if shutil.which("dpkg-deb") is None:
        pytest.fail("dpkg-deb is missing: the package cannot be built or checked")
    return _build(tmp_path_factory.mktemp("deb"))


@pytest.fixture(scope="session")
def listing(deb: Path) -> dict[str, str]:
    """``dpkg-deb -c``: each path (without the leading ``.``) and its line."""
    lines = subprocess.run(
        ["dpkg-deb", "-c", str(deb)], capture_output=True, text=True, check=True
    ).stdout.splitlines()
    paths = {}
    for line in lines:
        name = line.split(None, 5)[5].split(" -> ")[0]
        paths[name.removeprefix(".").rstrip("/") or "/"] = line
    return paths


def _unpack(deb: Path, root: Path) -> Path:
    """The package's files unpacked into ``root`` (``dpkg-deb -x`` and ``-e``), not installed."""
    subprocess.run(["dpkg-deb", "-x", str(deb), str(root)], check=True)
    subprocess.run(["dpkg-deb", "-e", str(deb), str(root / "DEBIAN")], check=True)
    return root


@pytest.fixture(scope="session")
def unpacked(deb: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The package's files unpacked into a directory (``dpkg-deb -x``), not installed."""
    return _unpack(deb, tmp_path_factory.mktemp("unpacked"))


def field(deb: Path, name: str) -> str:
    return subprocess.run(
        ["dpkg-deb", "-f", str(deb), name], capture_output=True, text=True, check=True
    ).stdout.strip()


def test_name_version_and_architecture(deb: Path) -> None:
    """SR-0.2: the file is srcs-supervisord_<version>_<arch>.deb and its control fields agree
    with pyproject.toml and this machine's architecture."""
    arch = subprocess.run(
        ["dpkg", "--print-architecture"], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert deb.name == f"srcs-supervisord_{_version()}_{arch}.deb"
    assert field(deb, "Package") == "srcs-supervisord"
    assert field(deb, "Version") == _version()
    assert field(deb, "Architecture") == arch


def test_depends_on_no_compiler_and_no_dev_package(deb: Path) -> None:
    """SR-0.2, SR-0.4: the robot needs Python 3.10 to 3.14, the C library and systemd (its
    sysusers and tmpfiles, run by the postinst), and no compiler, headers or -dev package
    (nothing is built on the robot); udev, which only applies the rule, is recommended, so a
    container installs the package without it (docs/containers.md); bash-completion too, which
    loads the completion of the robots' names."""
    depends = [d.strip() for d in field(deb, "Depends").split(",")]
    names = {re.split(r"[ (]", d)[0] for d in depends}
    assert {"python3", "libc6", "systemd"} <= names
    assert "udev" not in names, depends
    assert field(deb, "Recommends") == "udev, bash-completion"
    assert "python3 (>= 3.10)" in depends, depends
    assert "python3 (<< 3.15)" in depends, depends
    compilers = {"gcc", "cc", "build-essential", "pkg-config", "cpp", "clang"}
    assert not names & compilers, names
    assert not [n for n in names if n.endswith("-dev")], names
    assert not field(deb, "Pre-Depends")


def test_files_are_where_debian_puts_them(listing: dict[str, str]) -> None:
    """SR-0.2: units in /usr/lib/systemd/system, sysusers, tmpfiles and udev under /usr/lib,
    the program in /opt/srcsd, examples and docs under /usr/share/doc, man pages, bash
    completion; nothing in /etc or /usr/local, every file root's."""
    doc = "/usr/share/doc/srcs-supervisord"
    expected = {
        "/usr/lib/systemd/system/srcsd@.service",
        "/usr/lib/systemd/system/srcs-exporter@.service",
        "/usr/lib/systemd/system/srcs-fleet-agent@.service",
        "/usr/lib/systemd/system/srcs-rv.service",
        "/usr/lib/sysusers.d/srcsd.conf",
        "/usr/lib/sysusers.d/srcs-fleet-agent.conf",
        "/usr/lib/tmpfiles.d/srcsd.conf",
        "/usr/lib/udev/rules.d/60-srcs.rules",
        "/opt/srcsd/pyvenv.cfg",
        "/opt/srcsd/bin/python3",
        f"{doc}/copyright",
        f"{doc}/changelog.gz",
        "/usr/share/lintian/overrides/srcs-supervisord",
        f"{doc}/README.md",
        f"{doc}/docs/install.md",
        f"{doc}/examples/example-serial-gpio.toml",
        f"{doc}/examples/example-can.toml",
        f"{doc}/examples/prometheus/srcs-alerts.yml",
        f"{doc}/examples/srcsd.schema.json",
        f"{doc}/examples/robot_motion.py",
        f"{doc}/examples/robot-motion@.service",
        f"{doc}/examples/robot-motion.conf",
        "/opt/srcsd/lib/python3/site-packages/supervisord/cli/demo.toml",
        "/usr/share/man/man8/srcsd.8.gz",
        "/usr/share/man/man5/srcsd.toml.5.gz",
        "/usr/share/man/man1/srcsctl.1.gz",
        "/usr/share/man/man1/srcs-sim.1.gz",
        "/usr/share/man/man8/srcs-exporter.8.gz",
        "/usr/share/man/man8/srcs-fleet-agent.8.gz",
        "/usr/sbin/srcsd",
        "/usr/sbin/srcs-fleet-agent",
        "/usr/bin/srcsctl",
    }
    expected |= {f"/opt/srcsd/bin/{name}" for name in LAUNCHERS}
    expected |= {f"/opt/srcsd/lib/python{version}" for version in PYTHONS}
    expected |= {f"/usr/share/bash-completion/completions/{name}" for name in LAUNCHERS}
    assert not expected - listing.keys(), sorted(expected - listing.keys())
    assert not [p for p in listing if p.startswith(("/etc", "/usr/local", "/var", "/run"))]
    # No byte-code: postinst compiles for the robot's python3 (test_postinst_compiles_...).
    assert not [p for p in listing if "__pycache__" in p or p.endswith(".pyc")]
    assert all(" root/root " in line for line in listing.values())
    assert "/opt/srcsd/bin/srcsd -> " not in listing["/opt/srcsd/bin/srcsd"]  # a file
    assert listing["/usr/sbin/srcsd"].endswith("-> /opt/srcsd/bin/srcsd")


def test_the_motion_example_ships_as_in_the_source(unpacked: Path) -> None:
    """SR-0.2, SR-8.10: the motion service example, its unit and its user are in the package,
    where docs/bringup.md installs them from, the same bytes as examples/, not executable
    (documentation), and the unit reads the robot's socket from its config (``-R %i``)."""
    doc = unpacked / "usr/share/doc/srcs-supervisord/examples"
    for source in (
        "motion/robot_motion.py",
        "systemd/robot-motion@.service",
        "systemd/robot-motion.conf",
    ):
        shipped = doc / Path(source).name
        assert shipped.read_bytes() == (ROOT / "examples" / source).read_bytes(), source
        assert not shipped.stat().st_mode & 0o111, source
    unit = (doc / "robot-motion@.service").read_text()
    assert "robot_motion.py -R %i " in unit
    assert "--socket" not in unit


def test_the_unit_runs_the_packaged_program(unpacked: Path) -> None:
    """SR-0.2: the unit's ExecStart names the packaged launcher, which is executable."""
    unit = (unpacked / "usr/lib/systemd/system/srcsd@.service").read_text()
    (command,) = re.findall(r"^ExecStart=(\S+)", unit, re.MULTILINE)
    assert command == "/opt/srcsd/bin/srcsd"
    assert (unpacked / command.lstrip("/")).stat().st_mode & 0o111


def test_the_fleet_agent_ships_with_its_unit_and_user_and_is_not_enabled(
    unpacked: Path,
) -> None:
    """SR-13.13, SR-0.2: the fleet stop's agent is in the package with its unit and its user
    as units/ has them; the unit runs the packaged launcher as the user the sysusers file
    makes; postinst makes that user and enables or starts no agent (a fleet turns it on), an
    upgrade stops and restarts running agents with the supervisors, a purge removes the
    user and the instances' enable links."""
    systemd = unpacked / "usr/lib/systemd/system/srcs-fleet-agent@.service"
    sysusers = unpacked / "usr/lib/sysusers.d/srcs-fleet-agent.conf"
    assert systemd.read_bytes() == (ROOT / "units/srcs-fleet-agent@.service").read_bytes()
    assert sysusers.read_bytes() == (ROOT / "units/srcs-fleet-agent.sysusers.conf").read_bytes()
    unit = systemd.read_text()
    (command,) = re.findall(r"^ExecStart=(\S+)", unit, re.MULTILINE)
    assert command == "/opt/srcsd/bin/srcs-fleet-agent"
    assert (unpacked / command.lstrip("/")).stat().st_mode & 0o111
    (user,) = re.findall(r"^User=(\S+)", unit, re.MULTILINE)
    assert re.search(rf"^u {user}\s", sysusers.read_text(), re.MULTILINE)
    postinst = (unpacked / "DEBIAN/postinst").read_text()
    assert "systemd-sysusers srcs-fleet-agent.conf" in postinst
    # The agent's name is in no systemctl call of postinst; the only `systemctl enable` is
    # the first install's hint, for srcsd.
    assert not [line for line in postinst.splitlines() if re.search(r"systemctl.*fleet", line)]
    enables = [line.strip() for line in postinst.splitlines() if "systemctl enable" in line]
    assert enables == ["systemctl enable --now srcsd@ROBOT   # starts STOPPED: the operator's "
                       "takeover re-arms it"]  # fmt: skip
    assert "'srcs-fleet-agent@*.service'" in (unpacked / "DEBIAN/prerm").read_text()
    postrm = (unpacked / "DEBIAN/postrm").read_text()
    assert "*.wants/srcs-fleet-agent@*.service" in postrm
    assert re.search(r"^    for user in .*\bsrcs-fleet\b", postrm, re.MULTILINE)


def test_the_kernel_judges_counter_ships_with_its_unit_and_is_not_enabled(
    unpacked: Path,
) -> None:
    """SR-9.9, SR-0.2: srcs-rv.service is in the package as units/ has it; it runs the
    packaged Python on the packaged module; postinst enables or starts nothing of it (an
    integrator turns it on for a judged kernel), prerm stops it, a purge removes its enable
    link and its totals."""
    systemd = unpacked / "usr/lib/systemd/system/srcs-rv.service"
    assert systemd.read_bytes() == (ROOT / "units/srcs-rv.service").read_bytes()
    (command,) = re.findall(r"^ExecStart=(.+)$", systemd.read_text(), re.MULTILINE)
    assert command == "/opt/srcsd/bin/python3 -I -m supervisord.rv_watch"
    site = unpacked / "opt/srcsd/lib/python3/site-packages/supervisord"
    assert (site / "rv_watch.py").is_file()
    assert (site / "rv_count.py").is_file()
    postinst = (unpacked / "DEBIAN/postinst").read_text()
    assert "srcs-rv" not in postinst
    assert "srcs-rv.service" in (unpacked / "DEBIAN/prerm").read_text()
    postrm = (unpacked / "DEBIAN/postrm").read_text()
    assert "*.wants/srcs-rv.service" in postrm
    assert "/run/srcs-rv" in postrm


def test_the_packaged_agent_reaches_a_real_broker_with_its_own_mqtt_client(
    unpacked: Path, tmp_path: Path
) -> None:
    """SR-13.13: the package carries the agent's MQTT client, paho-mqtt, pure Python (one copy
    serves every Python); the packaged srcs-fleet-agent, run from the unpacked tree with its
    own environment only, connects to a real mosquitto with the fleet's mutual TLS and ACL and
    announces its robot online, as on a robot."""
    from tests.fleet_agent.agents import agent_command, wait_online  # noqa: PLC0415
    from tests.fleet_agent.broker import running_broker  # noqa: PLC0415

    site = unpacked / SITE
    (info,) = site.glob("paho_mqtt-*.dist-info")
    assert info.name == "paho_mqtt-2.1.0.dist-info"
    assert "Tag: py3-none-any" in (info / "WHEEL").read_text()
    assert (site / "paho/mqtt/client.py").is_file()
    assert not list((site / "paho").rglob("*.so"))
    with running_broker(tmp_path / "broker") as broker:
        command = agent_command(broker, "robot-a", tmp_path / "no-srcsd.sock")
        assert command[1:3] == ["-m", "supervisord.cli.fleet_agent"]
        launcher = str(unpacked / "opt/srcsd/bin/srcs-fleet-agent")
        log = (tmp_path / "agent.log").open("wb")
        agent = subprocess.Popen(
            [launcher, *command[3:]],
            env=_packaged_env(),
            cwd=tmp_path,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        log.close()
        try:
            wait_online(broker, {"robot-a"})
        finally:
            agent.terminate()
            code = agent.wait(10)
        assert code == 0, (tmp_path / "agent.log").read_text()


def test_no_conffiles_and_nothing_in_etc(unpacked: Path, listing: dict[str, str]) -> None:
    """SR-0.2: the package ships no file in /etc, so it has no conffiles: /etc/srcs and its
    robot configs are the administrator's, made by postinst and never overwritten."""
    assert not (unpacked / "DEBIAN/conffiles").exists()
    assert not [p for p in listing if p.startswith("/etc")]


def test_maintainer_scripts_parse_and_guard_systemctl(unpacked: Path) -> None:
    """SR-0.2: postinst, prerm and postrm pass sh -n, and each systemctl call sits behind the
    check that systemd runs (a chroot has none)."""
    for name in ("postinst", "prerm", "postrm"):
        script = unpacked / "DEBIAN" / name
        assert script.stat().st_mode & 0o111, f"{name} is not executable"
        subprocess.run(["sh", "-n", str(script)], check=True)
        text = script.read_text()
        assert text.startswith("#!/bin/sh\n")
        assert "set -e" in text
        if "systemctl " in text:
            assert "[ -d /run/systemd/system ]" in text, f"{name}: systemctl without a guard"


def test_postinst_does_what_the_hand_install_did(unpacked: Path) -> None:
    """SR-0.2: postinst runs systemd-sysusers, systemd-tmpfiles --create (which makes
    /etc/srcs), udevadm reload and trigger, and daemon-reload, as install.md step 3 did."""
    text = (unpacked / "DEBIAN/postinst").read_text()
    for command in (
        "systemd-sysusers srcsd.conf",
        "systemd-tmpfiles --create srcsd.conf",
        "udevadm control --reload",
        "udevadm trigger --action=add",
        "systemctl daemon-reload",
    ):
        assert command in text, command
    tmpfiles = (unpacked / "usr/lib/tmpfiles.d/srcsd.conf").read_text()
    assert re.search(r"^d /etc/srcs\s", tmpfiles, re.MULTILINE)


def test_only_purge_deletes_the_stop_record(unpacked: Path) -> None:
    """SR-7.4: postrm deletes /var/lib/srcsd (the stop record) in its purge branch only; a
    plain remove keeps it (the system tier removes and purges the installed package)."""
    text = (unpacked / "DEBIAN/postrm").read_text()
    branches = dict(re.findall(r"^(\w[\w |-]*)\)\n(.*?)^    ;;", text, re.MULTILINE | re.DOTALL))
    assert "/var/lib/srcsd" in branches["purge"]
    removal = [body for label, body in branches.items() if label != "purge"]
    assert not [body for body in removal if "/var/lib/srcsd" in body]
    for name in ("postinst", "prerm"):
        assert "/var/lib/srcsd" not in (unpacked / "DEBIAN" / name).read_text()


@pytest.mark.parametrize("name", LAUNCHERS)
def test_launchers_run_from_the_unpacked_tree(unpacked: Path, name: str) -> None:
    """SR-0.2: each launcher runs from wherever the tree is (here unpacked, not installed):
    each prints the package's version."""
    result = subprocess.run(
        [str(unpacked / "opt/srcsd/bin" / name), "--version"],
        env=_packaged_env(),
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout == f"{name} {_version()}\n"


def test_the_environment_is_its_own(unpacked: Path) -> None:
    """SR-0.2: the packaged interpreter imports the program and its compiled dependencies from
    the package's tree only (not from the developer's venv or Debian's dist-packages), and
    ``sys.executable -m`` reaches the same tree, as srcsctl demo and the testkit use it."""
    python = unpacked / "opt/srcsd/bin/python3"
    probe = (
        "import sys, supervisord, can, gpiod._ext, msgpack._cmsgpack, wrapt._wrappers\n"
        "print(sys.prefix); print(supervisord.__file__); print(sys.executable)\n"
        "print(any('dist-packages' in p for p in sys.path))\n"
    )
    # cwd: -c and -m put the working directory first on the path; not this repository.
    result = subprocess.run(
        [str(python), "-c", probe],
        env=_packaged_env(),
        capture_output=True,
        text=True,
        cwd=unpacked,
        timeout=60,
        check=True,
    )
    prefix, module, executable, dist_packages = result.stdout.split("\n")[:4]
    assert Path(prefix) == unpacked / "opt/srcsd"
    assert Path(module).resolve().is_relative_to(unpacked / "opt/srcsd/lib/python3/site-packages")
    assert Path(executable) == python
    assert dist_packages == "False"
    again = subprocess.run(
        [executable, "-m", "supervisord.cli.sim", "--version"],
        env=_packaged_env(),
        capture_output=True,
        text=True,
        cwd=unpacked,
        timeout=60,
        check=False,
    )
    assert again.returncode == 0, again.stderr
    assert _version() in again.stdout + again.stderr


def test_extensions_for_every_supported_python(unpacked: Path) -> None:
    """SR-0.2: every compiled extension is there for each Python from 3.10 (Ubuntu 22.04) to
    3.14 (Ubuntu 26.04), and lib/python3.X is the one site-packages for each; tomli, the TOML
    reader the program needs on 3.10 only, is bundled; no journal library is packaged (the
    journal is written directly)."""
    site = unpacked / SITE
    built: dict[Path, set[str]] = {}
    for path in site.rglob("*.so"):
        named = re.fullmatch(r"(.+)\.cpython-(\d+)-[\w-]+\.so", path.name)
        assert named is not None, f"{path}: not named for one Python version"
        built.setdefault(path.parent.relative_to(site) / named[1], set()).add(named[2])
    assert {Path("gpiod/_ext"), Path("msgpack/_cmsgpack"), Path("wrapt/_wrappers")} <= set(built)
    every = {version.replace(".", "") for version in PYTHONS}
    assert {module: tags for module, tags in built.items() if tags != every} == {}
    for version in PYTHONS:
        assert (unpacked / f"opt/srcsd/lib/python{version}").resolve() == site.parent
    assert list(site.glob("tomli-*.dist-info"))
    assert not (site / "systemd").exists()


def _glibc(text: str) -> tuple[int, int]:
    major, minor = text.split(".")[:2]
    return int(major), int(minor)


def test_libc_dependency_is_what_the_wheels_need(deb: Path, unpacked: Path) -> None:
    """SR-0.2: Depends names libc6 (>= X), X the newest C library a bundled wheel needs by its
    manylinux tags (a wheel: the oldest its tags name, for each Python, whose tags the merged
    WHEEL files keep); no extension module asks for a newer glibc symbol; and X is at most
    2.35, Ubuntu 22.04's, the oldest of the targets."""
    depends = [d.strip() for d in field(deb, "Depends").split(",")]
    (libc,) = [d for d in depends if d.startswith("libc6")]
    declared = re.fullmatch(r"libc6 \(>= (\d+\.\d+)\)", libc)
    assert declared is not None, libc
    legacy = {"manylinux1": "2.5", "manylinux2010": "2.12", "manylinux2014": "2.17"}
    needed = (0, 0)
    for wheel in (unpacked / SITE).glob("*.dist-info/WHEEL"):
        by_python: dict[str, list[tuple[int, int]]] = {}
        for line in wheel.read_text().splitlines():
            if not line.startswith("Tag:"):
                continue
            python, _, platforms = line[4:].strip().split("-")
            for platform in platforms.split("."):
                numbered = re.match(r"manylinux_(\d+)_(\d+)_", platform)
                if numbered is not None:
                    by_python.setdefault(python, []).append((int(numbered[1]), int(numbered[2])))
                elif platform != "any":
                    by_python.setdefault(python, []).append(_glibc(legacy[platform.split("_")[0]]))
        needed = max([needed, *(min(tags) for tags in by_python.values())])
    assert _glibc(declared[1]) == needed
    symbols = set()
    for module in (unpacked / SITE).rglob("*.so"):
        symbols |= {
            _glibc(v.decode()) for v in re.findall(rb"GLIBC_(\d+\.\d+)", module.read_bytes())
        }
    assert symbols, "no glibc symbol versions found in the extension modules"
    assert max(symbols) <= needed <= (2, 35)


def test_no_path_of_the_build_machine(deb: Path, tmp_path: Path) -> None:
    """SR-0.2: no file of the package (binaries and control files included) and no link names
    the build's work directory, this repository or the build's Python environment: pip's
    scripts of the dependencies and its direct_url.json once did."""
    root = _unpack(deb, tmp_path / "root")
    work = deb.parent.parent / "work"
    places = (work, ROOT, Path(sys.prefix))
    needles = {str(path).encode() for place in places for path in (place, place.resolve())}
    hits = []
    for path in sorted(root.rglob("*")):
        if path.is_symlink():
            data = os.readlink(path).encode()
        elif path.is_file():
            data = path.read_bytes()
        else:
            continue
        hits += [f"{path.relative_to(root)}: {n.decode()}" for n in sorted(needles) if n in data]
    assert hits == []


def test_two_builds_are_the_same_bytes(deb: Path, tmp_path: Path) -> None:
    """SR-0.2: a second build of the same tree, in another work directory, gives the same .deb
    byte for byte: every time is SOURCE_DATE_EPOCH's, the package holds no byte-code and no
    local path."""
    again = _build(tmp_path)
    if again.read_bytes() != deb.read_bytes():
        sums = [
            set(
                subprocess.run(
                    ["dpkg-deb", "-I", str(d), "md5sums"],
                    capture_output=True,
                    text=True,
                    check=True,
                ).stdout.splitlines()
            )
            for d in (deb, again)
        ]
        pytest.fail(f"the builds differ; files: {sorted(sums[0] ^ sums[1])[:10]}")


def test_lintian_finds_no_error_and_no_warning(deb: Path) -> None:
    """SR-0.2: Debian's checker passes the package: no error and no warning but those the
    package's overrides file overrides, and none of its overrides unused."""
    if shutil.which("lintian") is None:
        pytest.fail("lintian is missing (./dev test installs it)")
    result = subprocess.run(
        ["lintian", "--info", "--display-info", "--fail-on", "error,warning", str(deb)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    tags = [line for line in result.stdout.splitlines() if re.match(r"[EWIPX]: ", line)]
    bad = [t for t in tags if t.startswith(("E:", "W:")) or "-override" in t]
    assert bad == []
    assert result.returncode == 0, result.stdout + result.stderr


def test_every_lintian_override_says_why(unpacked: Path) -> None:
    """SR-0.2: each override in the package's lintian overrides file follows a comment that
    says why (a group of overrides may share one)."""
    text = (unpacked / "usr/share/lintian/overrides/srcs-supervisord").read_text()
    previous = ""
    overrides = 0
    for line in text.splitlines():
        if line and not line.startswith("#"):
            assert line.startswith("srcs-supervisord: "), line
            assert previous.startswith(("#", "srcs-supervisord: ")), f"no reason for {line}"
            overrides += 1
        previous = line
    assert overrides


def test_changelog_and_maintainer(deb: Path, unpacked: Path) -> None:
    """SR-0.2: the package carries packaging/changelog as changelog.gz (a native package's
    name), in Debian's format, its top entry at pyproject.toml's version; its Maintainer is the
    project's fixed address, the changelog's, whatever DEBEMAIL the build ran with."""
    changelog = ROOT / "packaging/changelog"
    if shutil.which("dpkg-parsechangelog") is None:
        pytest.fail("dpkg-parsechangelog is missing (dpkg-dev, which lintian brings)")
    parsed = {
        name: subprocess.run(
            ["dpkg-parsechangelog", "-l", str(changelog), "-S", name],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        for name in ("Source", "Version", "Maintainer")
    }
    assert parsed["Source"] == "srcs-supervisord"
    assert parsed["Version"] == _version()
    assert gzip.decompress((unpacked / DOC / "changelog.gz").read_bytes()) == changelog.read_bytes()
    maintainer = field(deb, "Maintainer")
    assert maintainer == parsed["Maintainer"]
    assert re.fullmatch(r"[^<>]+ <[^@<>\s]+@[\w-]+(\.[\w-]+)+>", maintainer), maintainer
    assert SOMEONE_ELSE not in maintainer
    assert "localhost" not in maintainer
    assert "root@" not in maintainer


def test_copyright_covers_every_bundled_distribution(unpacked: Path) -> None:
    """SR-0.2: the copyright file is machine-readable (DEP-5), names each distribution bundled
    in the environment in a paragraph with its licence, and gives every licence's text or the
    common-licenses file that has it; the build's own check fails when a paragraph is missing
    (here wrapt's)."""
    text = (unpacked / DOC / "copyright").read_text()
    assert text == (ROOT / "packaging/copyright").read_text()
    assert text.startswith(
        "Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/\n"
    )
    site = unpacked / SITE
    bundled = set()
    for info in site.glob("*.dist-info"):
        name = re.search(r"^Name: (\S+)$", (info / "METADATA").read_text(), re.MULTILINE)
        assert name is not None, info
        bundled.add(name[1])
    named = set(re.findall(r"^Distribution: (\S+)$", text, re.MULTILINE))
    assert named == bundled - {"srcs-supervisord"}
    paragraphs = text.split("\n\n")
    texts = {
        p.split("\n")[0].removeprefix("License: ") for p in paragraphs if p.startswith("License:")
    }
    for paragraph in paragraphs:
        if paragraph.startswith("Files:"):
            licence = re.search(r"^License: (.+)((?:\n .*)*)", paragraph, re.MULTILINE)
            assert licence is not None, paragraph
            names = re.split(r" or | and ", licence[1])
            assert licence[2].strip() or set(names) <= texts, paragraph
    build_deb = build_script.build_deb()
    build_deb.check_copyright(site, text)
    without = re.sub(r"\n\nFiles: [^\n]*/wrapt/\*.*?(?=\n\n)", "", text, flags=re.DOTALL)
    assert "Distribution: wrapt" not in without
    with pytest.raises(build_deb.BuildError, match="wrapt"):
        build_deb.check_copyright(site, without)


def test_the_first_install_hint_runs_on_a_minimal_system(unpacked: Path) -> None:
    """SR-0.2, SR-8.18: the next steps a first install prints are commands a minimal Debian
    has (coreutils, systemd: a dependency) or the package's own, never ``editor`` (absent
    from a minimal system: the file to edit is named), and end with commissioning the VSC."""
    text = (unpacked / "DEBIAN/postinst").read_text()
    block = text.split("<<'NEXT'\n", 1)[1].split("\nNEXT", 1)[0]
    steps = [line.strip() for line in block.splitlines()[1:]]
    present = {"cp", "systemctl", "srcsd", "srcsctl"}
    for step in steps:
        if not step.startswith("#"):
            assert step.split()[0] in present, step
    assert "srcsctl -R ROBOT commission" in block
    assert "/etc/srcs/ROBOT.toml" in block


def test_postinst_compiles_for_the_installed_python(deb: Path, tmp_path: Path) -> None:
    """SR-0.2: postinst's byte-compile, run on an unpacked tree, compiles every module of the
    environment for the python3 the environment links to (here this machine's): the package
    carries byte-code for no version, as it serves every one from 3.10 to 3.14."""
    root = _unpack(deb, tmp_path / "root")
    postinst = (root / "DEBIAN/postinst").read_text()
    (command,) = re.findall(
        r"^\s*(/opt/srcsd/bin/python3 -m compileall [^>\n]*?)\s*>", postinst, re.MULTILINE
    )
    args = [arg.replace("/opt/srcsd", str(root / "opt/srcsd")) for arg in shlex.split(command)]
    subprocess.run(args, env=_packaged_env(), capture_output=True, timeout=300, check=True)
    probe = (
        "import importlib.util, pathlib, sys\n"
        "site = pathlib.Path(sys.argv[1])\n"
        "modules = sorted(site.rglob('*.py'))\n"
        "compiled = [pathlib.Path(importlib.util.cache_from_source(p)) for p in modules]\n"
        "missing = [p for p, pyc in zip(modules, compiled) if not pyc.is_file()]\n"
        "print(sys.implementation.cache_tag, len(modules), len(missing), *missing[:5])\n"
    )
    result = subprocess.run(
        [str(root / "opt/srcsd/bin/python3"), "-c", probe, str(root / SITE)],
        env=_packaged_env(),
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    tag, modules, missing, *names = result.stdout.split()
    assert tag.removeprefix("cpython-") in {v.replace(".", "") for v in PYTHONS}
    assert int(modules) > 100
    assert (int(missing), names) == (0, [])
    assert (root / SITE / f"supervisord/__pycache__/__init__.{tag}.pyc").is_file()


def test_replay_mcap_works_from_the_installed_tree(unpacked: Path, tmp_path: Path) -> None:
    """SR-7.15: on a robot, where the window is, the package's own ``srcsctl replay --mcap``
    writes the stop's MCAP file (the library is bundled, and nothing tells the team to
    ``pip install`` what no index has); the file is whole (the mcap reader reads every
    message); the compiled compression libraries mcap names are not bundled (NOT_BUNDLED)."""
    from mcap.reader import make_reader  # noqa: PLC0415 - the reader is the test's, not the package's

    from tests.record.stop_kinds import KINDS, RECORD  # noqa: PLC0415

    story = KINDS["remote_estop"]()
    story.write(tmp_path)
    out = tmp_path / "stop.mcap"
    done = subprocess.run(
        [
            str(unpacked / "opt/srcsd/bin/srcsctl"),
            *("replay", str(story.stop["seq"]), "--file", str(tmp_path / RECORD)),
            *("--mcap", str(out)),
        ],
        env=_packaged_env(),
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"mcap: wrote {out}" in done.stdout + done.stderr
    with out.open("rb") as file:
        messages = sum(1 for _ in make_reader(file).iter_messages())
    assert messages > 0
    site = unpacked / SITE
    assert list(site.glob("mcap-*.dist-info"))
    assert not list(site.glob("zstandard*"))
    assert not list(site.glob("lz4*"))

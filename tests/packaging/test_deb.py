"""The Debian package that ``./dev deb`` builds (packaging/build_deb.py, docs/install.md): its
files where Debian puts them (SR-0.2: the units, users, directories and udev rule that put the
supervisor in its place), no compiler or -dev dependency, maintainer scripts that parse and
never delete the stop record on a plain remove (SR-7.4), and launchers that run from an
unpacked tree. Built once per session; nothing is ever installed on this machine (the system
tier installs it in its guest, docs/system-tier.md)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from supervisord.config import toml

ROOT = Path(__file__).resolve().parents[2]
LAUNCHERS = ("srcsd", "srcsctl", "srcs-sim", "srcs-exporter")


def _version() -> str:
    with (ROOT / "pyproject.toml").open("rb") as handle:
        return str(toml.load(handle)["project"]["version"])


@pytest.fixture(scope="session")
def deb(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The package built from this tree, once per session, in a directory of the session's own."""
    if shutil.which("dpkg-deb") is None:
        pytest.fail("dpkg-deb is missing: the package cannot be built or checked")
    out = tmp_path_factory.mktemp("deb")
    result = subprocess.run(
        [
            sys.executable,
            "packaging/build_deb.py",
            *("--out", str(out / "dist"), "--work", str(out / "work")),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    return Path(result.stdout.strip())


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


@pytest.fixture(scope="session")
def unpacked(deb: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The package's files unpacked into a directory (``dpkg-deb -x``), not installed."""
    root = tmp_path_factory.mktemp("unpacked")
    subprocess.run(["dpkg-deb", "-x", str(deb), str(root)], check=True)
    subprocess.run(["dpkg-deb", "-e", str(deb), str(root / "DEBIAN")], check=True)
    return root


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
    """SR-0.2: the robot needs Python, systemd and udev, and no compiler, headers or -dev
    package (nothing is built on the robot)."""
    depends = [d.strip() for d in field(deb, "Depends").split(",")]
    names = {re.split(r"[ (]", d)[0] for d in depends}
    assert {"python3", "systemd", "udev"} <= names
    assert "python3 (>= 3.11)" in depends, depends
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
        "/usr/lib/sysusers.d/srcsd.conf",
        "/usr/lib/tmpfiles.d/srcsd.conf",
        "/usr/lib/udev/rules.d/60-srcs.rules",
        "/opt/srcsd/pyvenv.cfg",
        "/opt/srcsd/bin/python3",
        f"{doc}/copyright",
        f"{doc}/README.md",
        f"{doc}/docs/install.md",
        f"{doc}/examples/example-serial-gpio.toml",
        f"{doc}/examples/example-can.toml",
        f"{doc}/examples/prometheus/srcs-alerts.yml",
        f"{doc}/examples/srcsd.schema.json",
        "/opt/srcsd/lib/python3/site-packages/supervisord/cli/demo.toml",
        "/usr/share/man/man8/srcsd.8.gz",
        "/usr/share/man/man1/srcsctl.1.gz",
        "/usr/share/man/man1/srcs-sim.1.gz",
        "/usr/share/man/man8/srcs-exporter.8.gz",
        "/usr/sbin/srcsd",
        "/usr/bin/srcsctl",
    }
    expected |= {f"/opt/srcsd/bin/{name}" for name in LAUNCHERS}
    expected |= {f"/usr/share/bash-completion/completions/{name}" for name in LAUNCHERS}
    assert not expected - listing.keys(), sorted(expected - listing.keys())
    assert not [p for p in listing if p.startswith(("/etc", "/usr/local", "/var", "/run"))]
    assert all(" root/root " in line for line in listing.values())
    assert "/opt/srcsd/bin/srcsd -> " not in listing["/opt/srcsd/bin/srcsd"]  # a file
    assert listing["/usr/sbin/srcsd"].endswith("-> /opt/srcsd/bin/srcsd")


def test_the_unit_runs_the_packaged_program(unpacked: Path) -> None:
    """SR-0.2: the unit's ExecStart names the packaged launcher, which is executable."""
    unit = (unpacked / "usr/lib/systemd/system/srcsd@.service").read_text()
    (command,) = re.findall(r"^ExecStart=(\S+)", unit, re.MULTILINE)
    assert command == "/opt/srcsd/bin/srcsd"
    assert (unpacked / command.lstrip("/")).stat().st_mode & 0o111


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
        capture_output=True,
        text=True,
        cwd=unpacked,
        timeout=60,
        check=False,
    )
    assert again.returncode == 0, again.stderr
    assert _version() in again.stdout + again.stderr


def test_extensions_for_every_supported_python(unpacked: Path) -> None:
    """SR-0.2: every compiled extension is there for Python 3.11 (Debian 12) and 3.12 (Ubuntu
    24.04), and no journal library is packaged (the journal is written directly)."""
    site = unpacked / "opt/srcsd/lib/python3/site-packages"
    built = {p.relative_to(site) for p in site.rglob("*.so")}
    for_311 = {p for p in built if ".cpython-311-" in p.name}
    assert for_311, "no extension modules found"
    for path in for_311:
        assert path.with_name(path.name.replace("-311-", "-312-")) in built, path
    assert not (site / "systemd").exists()
    assert (unpacked / "opt/srcsd/lib/python3.11").resolve() == site.parent
    assert (unpacked / "opt/srcsd/lib/python3.12").resolve() == site.parent

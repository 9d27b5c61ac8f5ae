"""Build the ROS 2 bridge's wheel and ``python3-srcs-ros2_VERSION_all.deb`` (docs/ros2.md
"Install").

usage: ./dev deb --ros2 [--out DIR] [--work DIR]

The wheel is built from ``ros2/`` with its links resolved (the bridge and the client library it
imports, nothing of the daemon), by this environment's setuptools: no build isolation and no
index, so it builds without a network. The package holds the wheel's modules in
``/usr/lib/python3/dist-packages``, the directory that Debian's and Ubuntu's ``python3``
searches whatever its version (3.10 on Ubuntu 22.04 to 3.14 on 26.04), and
``/usr/bin/srcs-ros2``, run by ``/usr/bin/python3``: the distribution's Python, the one its ROS
uses. It depends on ``python3`` alone: rclpy and the message packages come from the ROS
installation (rosdep installs them from ``ros2/package.xml``), never from this package.

No byte-code (one tree serves every Python version) and no maintainer scripts: the launcher
does not write ``__pycache__`` into ``/usr`` either, so removing the package leaves nothing.
Deterministic: the same tree and ``SOURCE_DATE_EPOCH`` (default: the last commit's time) give
the same bytes.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path, PurePosixPath
from xml.etree import ElementTree

REPO = Path(__file__).resolve().parents[1]
SOURCE = REPO / "ros2"
PACKAGE = "python3-srcs-ros2"
SITE = Path("usr/lib/python3/dist-packages")
DOC = Path("usr/share/doc", PACKAGE)
PYTHON_MIN = "3.10"
"""Humble's (Ubuntu 22.04); Jazzy and Kilted run 3.12, Lyrical 3.14."""

LAUNCHER = """#!/usr/bin/python3
# srcs-ros2, from the {package} package (docs/ros2.md): the ROS 2 bridge of the SRCS
# supervisor. Run it in a ROS environment (source /opt/ros/DISTRO/setup.bash first): rclpy and
# the message packages come from there.
import sys

# No __pycache__ under /usr: the package does not own it, so its removal would leave it.
sys.dont_write_bytecode = True

from supervisord.cli.ros2 import main

if __name__ == "__main__":
    sys.exit(main())
"""

EXAMPLES = (
    REPO / "units/srcs-ros2@.service",
    REPO / "examples/ros2/srcs_bridge.launch.py",
    REPO / "examples/ros2/srcs_bridge.yaml",
)


class BuildError(Exception):
    """A step of the build failed; the message says which and why."""


def run(*cmd: str | Path, cwd: Path = REPO, env: dict[str, str] | None = None) -> str:
    result = subprocess.run(
        [str(c) for c in cmd], cwd=cwd, capture_output=True, text=True, env=env, check=False
    )
    if result.returncode != 0:
        raise BuildError(
            f"{' '.join(str(c) for c in cmd)} failed ({result.returncode}):\n"
            f"{result.stdout[-3000:]}{result.stderr[-3000:]}"
        )
    return result.stdout


def manifest() -> tuple[str, str]:
    """The ROS package's name and version, from ``ros2/package.xml``."""
    root = ElementTree.parse(SOURCE / "package.xml").getroot()  # noqa: S314 -- our own file
    name, version = root.findtext("name"), root.findtext("version")
    if not name or not version:
        raise BuildError(f"{SOURCE / 'package.xml'}: no name or version")
    return name.strip(), version.strip()


def maintainer() -> str:
    """The package's Maintainer, ``NAME <EMAIL>``: ``ros2/package.xml``'s, the one place the
    bridge's maintainer is written, never the builder's DEBEMAIL, so that two builds by
    different people are the same bytes."""
    root = ElementTree.parse(SOURCE / "package.xml").getroot()  # noqa: S314 -- our own file
    found = root.find("maintainer")
    if found is None or not (found.text or "").strip() or not found.get("email"):
        raise BuildError(f"{SOURCE / 'package.xml'}: no maintainer with an email")
    return f"{(found.text or '').strip()} <{found.get('email')}>"


def source_epoch() -> int:
    if "SOURCE_DATE_EPOCH" in os.environ:
        return int(os.environ["SOURCE_DATE_EPOCH"])
    try:
        return int(run("git", "log", "-1", "--format=%ct").strip())
    except (BuildError, ValueError):
        return 0


def normalise(root: Path, epoch: int) -> None:
    """Modes and times that do not depend on the build machine's umask or clock."""
    for path in [root, *root.rglob("*")]:
        if not path.is_symlink():
            executable = path.is_dir() or path.stat().st_mode & 0o111
            path.chmod(0o755 if executable else 0o644)
        os.utime(path, (epoch, epoch), follow_symlinks=False)


def build_wheel(work: Path, epoch: int) -> Path:
    """The wheel, from a copy of ``ros2/`` whose links are files (a build leaves nothing in
    the tree, and the wheel does not depend on where the repository is)."""
    source = work / "src"
    shutil.copytree(
        SOURCE,
        source,
        symlinks=False,
        ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "build", "*.egg-info"),
    )
    normalise(source, epoch)
    env = {**os.environ, "SOURCE_DATE_EPOCH": str(epoch)}
    pip = (sys.executable, "-m", "pip", "--disable-pip-version-check", "-q")
    run(
        *pip,
        "wheel",
        "--no-deps",
        "--no-build-isolation",
        "--no-index",
        "-w",
        work,
        source,
        env=env,
    )
    wheels = list(work.glob("*.whl"))
    if len(wheels) != 1:
        raise BuildError(f"expected one wheel in {work}, found {[w.name for w in wheels]}")
    return wheels[0]


def install_wheel(wheel: Path, root: Path) -> None:
    """The wheel's modules and metadata into ``SITE``. Left out: the ament index data (only a
    ROS prefix such as a colcon install reads it) and ``RECORD`` (dpkg owns these files, so pip
    refuses to uninstall them)."""
    site = root / SITE
    with zipfile.ZipFile(wheel) as archive:
        for member in archive.infolist():
            name = PurePosixPath(member.filename)
            top = name.parts[0]
            if member.is_dir() or top.endswith(".data"):
                continue
            if top.endswith(".dist-info") and name.name == "RECORD":
                continue
            target = site / name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(archive.read(member))


def install_files(root: Path) -> None:
    """The launcher; the copyright, this page and the examples under ``DOC``."""
    launcher = root / "usr/bin/srcs-ros2"
    launcher.parent.mkdir(parents=True)
    launcher.write_text(LAUNCHER.format(package=PACKAGE))
    launcher.chmod(0o755)
    put = [
        (REPO / "packaging/copyright", root / DOC / "copyright"),
        (REPO / "docs/ros2.md", root / DOC / "ros2.md"),
    ]
    put += [(path, root / DOC / "examples" / path.name) for path in EXAMPLES]
    for source, target in put:
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source, target)


def control(root: Path, version: str) -> str:
    size = sum(p.lstat().st_size for p in root.rglob("*") if not p.is_dir()) // 1024 + 1
    return (
        f"Package: {PACKAGE}\n"
        f"Version: {version}\n"
        "Architecture: all\n"
        f"Maintainer: {maintainer()}\n"
        f"Installed-Size: {size}\n"
        # ROS's own packages are not Debian's: rosdep installs them (ros2/package.xml).
        f"Depends: python3 (>= {PYTHON_MIN})\n"
        "Section: python\n"
        "Priority: optional\n"
        "Description: ROS 2 bridge of the SRCS safety supervisor\n"
        " srcs-ros2 brings the SRCS remote, the supervisor's state and its stops into\n"
        " a robot's ROS 2 graph, as a client of srcsd's socket API, and gates cmd_vel\n"
        " on the supervisor being in RUN. It needs a ROS 2 installation (Humble,\n"
        " Jazzy, Kilted or Lyrical) for rclpy and the message packages.\n"
    )


def md5sums(root: Path) -> str:
    lines = []
    for path in sorted(root.rglob("*")):
        relative = path.relative_to(root)
        if relative.parts[0] == "DEBIAN" or path.is_symlink() or not path.is_file():
            continue
        lines.append(f"{hashlib.md5(path.read_bytes()).hexdigest()}  {relative}\n")  # noqa: S324
    return "".join(lines)


def build(out: Path, work: Path) -> tuple[Path, Path]:
    """The .deb and the wheel, both in ``out``."""
    _, version = manifest()
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    epoch = source_epoch()
    wheel = build_wheel(work, epoch)
    root = work / "root"
    install_wheel(wheel, root)
    install_files(root)
    normalise(root, epoch)
    debian = root / "DEBIAN"
    debian.mkdir()
    (debian / "control").write_text(control(root, version))
    (debian / "md5sums").write_text(md5sums(root))
    normalise(root, epoch)
    out.mkdir(parents=True, exist_ok=True)
    deb = out / f"{PACKAGE}_{version}_all.deb"
    env = {**os.environ, "SOURCE_DATE_EPOCH": str(epoch)}
    run("dpkg-deb", "--root-owner-group", "-Zxz", "--build", root, deb, env=env)
    shipped = out / wheel.name
    shutil.copyfile(wheel, shipped)
    return deb, shipped


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=REPO / "dist", help="where the files go")
    parser.add_argument(
        "--work", type=Path, default=REPO / "build/ros2-deb", help="scratch (emptied first)"
    )
    args = parser.parse_args()
    if shutil.which("dpkg-deb") is None:
        print("build_ros2_deb: dpkg-deb not found: build on Debian or Ubuntu", file=sys.stderr)
        return 1
    try:
        deb, wheel = build(args.out.resolve(), args.work.resolve())
    except BuildError as error:
        print(f"build_ros2_deb: {error}", file=sys.stderr)
        return 1
    print(deb)
    print(wheel)
    return 0


if __name__ == "__main__":
    sys.exit(main())

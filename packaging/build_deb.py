"""Build srcs-supervisord_VERSION_ARCH.deb from this repository (``./dev deb``; docs/install.md).

usage: .venv/bin/python packaging/build_deb.py [--arch ARCH] [--out DIR] [--work DIR] [--fetch]

The program goes to ``/opt/srcsd`` as a virtual environment with no interpreter of its own:
``bin/python3`` is a link to ``/usr/bin/python3``, ``pyvenv.cfg`` names ``/usr/bin``, and the
pinned dependencies (``requirements/run.txt``, hash-checked) are installed from wheels into
``lib/python3/site-packages``, which ``lib/python3.11`` and ``lib/python3.12`` both point to.
Each compiled extension is there once per Python version (``*.cpython-311-*.so`` beside
``*.cpython-312-*.so``), so one package serves Debian 12 (3.11) and Ubuntu 24.04 (3.12).
The commands in ``bin/`` are launchers that find the environment from their own location, so
the tree runs wherever it is unpacked (docs/install.md "What the package contains", and why a
venv rather than a plain ``--target`` directory: the daemon's tools start
``sys.executable -m supervisord...``, which must see the same libraries).

Nothing here is compiled: every dependency is a wheel, the journal is written without
libsystemd. Man pages and completion come from ``python -m supervisord.cli.reference``; the
build fails if that module is missing.
"""

from __future__ import annotations

import argparse
import filecmp
import gzip
import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import tomllib

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "srcs-supervisord"
PREFIX = Path("opt/srcsd")
SITE = PREFIX / "lib/python3/site-packages"
PYTHONS = ("3.11", "3.12")
"""The Python versions whose extension modules are bundled: Debian 12, Ubuntu 24.04. The
daemon needs 3.11 or newer (tomllib, datetime.UTC), so Ubuntu 22.04's 3.10 cannot run it."""
GLIBC = "2_35"
"""manylinux_2_35: the oldest C library of the targets (Ubuntu 22.04's 2.35; Debian 12 has 2.36,
Ubuntu 24.04 2.39). Only wheels that run on all of them are taken."""
MACHINES = {"amd64": "x86_64", "arm64": "aarch64"}
"""Debian architecture -> the wheels' machine name."""
LEFT_OUT = {"srcs-ros2"}
"""Console scripts not packaged: the ROS 2 bridge needs rclpy from a ROS installation and is
installed into a venv on ROS's own Python (docs/ros2.md)."""

LAUNCHER = """#!/bin/sh
'''exec' "$(dirname -- "$(readlink -f -- "$0")")/python3" "$0" "$@"
' '''
# {name}, from the {package} package. The two lines above are shell: they run this file
# with the python3 beside it (a link to /usr/bin/python3 in this virtual environment), so
# the tree works wherever it is; for Python they are a string.
import sys

from {module} import {function}

if __name__ == "__main__":
    sys.exit({function}())
"""

PYVENV_CFG = """home = /usr/bin
include-system-site-packages = false
"""


class BuildError(Exception):
    """A step of the build failed; the message says which and why."""


def run(*cmd: str | Path, cwd: Path = REPO) -> str:
    result = subprocess.run(
        [str(c) for c in cmd], cwd=cwd, capture_output=True, text=True, check=False
    )
    if result.returncode != 0:
        raise BuildError(
            f"{' '.join(str(c) for c in cmd)} failed ({result.returncode}):\n"
            f"{result.stdout[-3000:]}{result.stderr[-3000:]}"
        )
    return result.stdout


def pip(*args: str | Path) -> None:
    run(sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", *args)


def project() -> dict[str, object]:
    with (REPO / "pyproject.toml").open("rb") as handle:
        data: dict[str, object] = tomllib.load(handle)["project"]
    return data


def platforms(machine: str) -> list[str]:
    """pip's --platform for every manylinux tag up to GLIBC (pip takes each tag literally)."""
    newest = int(GLIBC.split("_")[1])
    tags = [f"manylinux_2_{minor}_{machine}" for minor in range(17, newest + 1)]
    tags.append(f"manylinux2014_{machine}")
    return [arg for tag in tags for arg in ("--platform", tag)]


def wheel_args(version: str, machine: str) -> list[str | Path]:
    abi = "cp" + version.replace(".", "")
    return [
        *("--no-deps", "--only-binary=:all:", "--python-version", version),
        *("--implementation", "cp", "--abi", abi, *platforms(machine)),
        *("--require-hashes", "-r", REPO / "requirements/run.txt"),
    ]


def fetch_wheels(machine: str, wheels: Path) -> None:
    """The pinned wheels for every Python version, in ``wheels``: from there when they are
    all there (the tests build without a network), else downloaded. Hash-checked both ways."""
    for version in PYTHONS:
        args = wheel_args(version, machine)
        try:
            pip("download", "--no-index", "--find-links", wheels, "--dest", wheels, *args)
        except BuildError:
            try:
                pip("download", "--dest", wheels, *args)
            except BuildError as error:
                raise BuildError(
                    f"the wheels for Python {version} are neither in {wheels} nor "
                    f"downloadable: {error}"
                ) from None


def install_dependencies(work: Path, machine: str, site: Path, wheels: Path) -> None:
    """requirements/run.txt, hash-checked, once per Python version; the trees must be equal
    but for the extension modules, which are merged into ``site``."""
    fetch_wheels(machine, wheels)
    trees = []
    for version in PYTHONS:
        tree = work / f"deps-{version}"
        pip(
            "install",
            *("--target", tree, "--no-compile", "--no-index", "--find-links", wheels),
            *wheel_args(version, machine),
        )
        trees.append(tree)
    first, *others = trees
    shutil.copytree(first, site, symlinks=True)
    for tree in others:
        for path in sorted(tree.rglob("*")):
            relative = path.relative_to(tree)
            target = site / relative
            if path.is_dir() or relative.parts[0].endswith(".dist-info"):
                continue  # a wheel's tags and RECORD differ by version; the code must not
            if ".so" in path.suffixes:
                if target.exists() and not filecmp.cmp(path, target, shallow=False):
                    raise BuildError(f"{relative}: differs between Python versions")
                shutil.copy2(path, target)
            elif not target.exists() or not filecmp.cmp(path, target, shallow=False):
                raise BuildError(
                    f"{relative}: the wheels for Python {PYTHONS} differ in more than their "
                    "extension modules; one shared site-packages cannot hold them"
                )
    for extension in site.rglob(f"*.cpython-{PYTHONS[0].replace('.', '')}-*.so"):
        for version in PYTHONS[1:]:
            tag = version.replace(".", "")
            if not list(extension.parent.glob(f"{extension.name.split('.')[0]}.cpython-{tag}-*")):
                raise BuildError(f"{extension}: no build for Python {version}")


def install_program(work: Path, site: Path) -> None:
    """This repository as a wheel (no dependencies: they are above), its modules compiled."""
    source = work / "src"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, source / name)
    shutil.copytree(
        REPO / "supervisord",
        source / "supervisord",
        ignore=shutil.ignore_patterns("__pycache__", "*.pyc"),
    )
    pip("wheel", "--no-deps", "--no-build-isolation", "-w", work / "wheel", source)
    (wheel,) = (work / "wheel").glob("*.whl")
    pip("install", "--target", work / "own", "--no-deps", "--no-compile", wheel)
    shutil.rmtree(work / "own/bin", ignore_errors=True)
    for path in (work / "own").iterdir():
        shutil.move(path, site / path.name)


def write_environment(root: Path, scripts: dict[str, str]) -> list[str]:
    """pyvenv.cfg, the interpreter links, lib/python3.X -> python3, the launchers."""
    prefix = root / PREFIX
    (prefix / "pyvenv.cfg").write_text(PYVENV_CFG)
    bin_dir = prefix / "bin"
    bin_dir.mkdir(parents=True)
    (bin_dir / "python3").symlink_to("/usr/bin/python3")
    (bin_dir / "python").symlink_to("python3")
    for version in PYTHONS:
        (prefix / f"lib/python{version}").symlink_to("python3")
    names = []
    for name, target in sorted(scripts.items()):
        if name in LEFT_OUT:
            continue
        module, function = target.split("#")[0].strip().split(":")
        launcher = bin_dir / name
        launcher.write_text(
            LAUNCHER.format(name=name, package=PACKAGE, module=module, function=function)
        )
        launcher.chmod(0o755)
        names.append(name)
    # On the path: the admin tools in /usr/sbin (their man pages are in section 8).
    for name in names:
        where = "usr/sbin" if name in ("srcsd", "srcs-exporter") else "usr/bin"
        link = root / where / name
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(f"/{PREFIX}/bin/{name}")
    return names


def compile_modules(root: Path, site: Path) -> None:
    """Byte-code for this build's Python, so that the service (ProtectSystem=strict: it cannot
    write /opt) starts without compiling; postinst compiles for another version. Run after the
    sources have their final times: the byte-code records them. Tracebacks name /opt/srcsd."""
    run(sys.executable, "-m", "compileall", "-q", "-j", "0", "-s", root, "-p", "/", site)


def install_files(root: Path, names: list[str]) -> None:
    """Units, sysusers, tmpfiles, udev; docs and examples; man pages and completion."""
    units = REPO / "units"
    put: list[tuple[Path, Path]] = [
        (units / "srcsd@.service", Path("usr/lib/systemd/system/srcsd@.service")),
        (units / "srcs-exporter@.service", Path("usr/lib/systemd/system/srcs-exporter@.service")),
        (units / "srcsd.sysusers.conf", Path("usr/lib/sysusers.d/srcsd.conf")),
        (units / "srcsd.tmpfiles.conf", Path("usr/lib/tmpfiles.d/srcsd.conf")),
        (units / "60-srcs.rules", Path("usr/lib/udev/rules.d/60-srcs.rules")),
    ]
    doc = Path("usr/share/doc", PACKAGE)
    put += [(REPO / "README.md", doc / "README.md")]
    put += [(REPO / "packaging/copyright", doc / "copyright")]
    put += [(path, doc / "docs" / path.name) for path in sorted((REPO / "docs").glob("*.md"))]
    put += [(path, doc / "examples" / path.name) for path in sorted((REPO / "config").glob("*"))]
    put += [(units / "srcs-ros2@.service", doc / "examples/srcs-ros2@.service")]
    for source, target in put:
        if source.is_dir():
            shutil.copytree(source, root / target)
        else:
            (root / target).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, root / target)

    generated = root.parent / "generated"
    for kind in ("man", "completion"):
        # Generated from the parsers by a module of the program (docs/srcsctl.md).
        try:
            run(sys.executable, "-m", "supervisord.cli.reference", kind, generated / kind)
        except BuildError as error:
            raise BuildError(f"man pages and completion could not be generated: {error}") from None
    for page in sorted((generated / "man").iterdir()):
        section = page.suffix.lstrip(".")
        if not section.isdigit():
            continue
        packed_page = root / f"usr/share/man/man{section}/{page.name}.gz"
        packed_page.parent.mkdir(parents=True, exist_ok=True)
        # mtime=0: the same page gives the same bytes.
        with page.open("rb") as raw, gzip.GzipFile(packed_page, "wb", 9, mtime=0) as packed:
            shutil.copyfileobj(raw, packed)
    completions = root / "usr/share/bash-completion/completions"
    completions.mkdir(parents=True)
    for name in names:
        source = generated / "completion" / name
        if not source.is_file():
            raise BuildError(f"no bash completion for {name} in {generated / 'completion'}")
        shutil.copy2(source, completions / name)
    for name in names:
        if not list((root / "usr/share/man").glob(f"man*/{name}.*.gz")):
            raise BuildError(f"no man page for {name}")


def control(root: Path, version: str, arch: str) -> str:
    size = sum(p.lstat().st_size for p in root.rglob("*") if not p.is_dir()) // 1024 + 1
    maintainer = os.environ.get("DEBFULLNAME", "srcs-supervisord maintainers")
    email = os.environ.get("DEBEMAIL", "root@localhost")
    python_min, python_next = PYTHONS[0], f"3.{int(PYTHONS[-1].split('.')[1]) + 1}"
    return (
        f"Package: {PACKAGE}\n"
        f"Version: {version}\n"
        f"Architecture: {arch}\n"
        f"Maintainer: {maintainer} <{email}>\n"
        f"Installed-Size: {size}\n"
        # The interpreter the venv links to; systemd for the units, sysusers and tmpfiles
        # (and systemctl); udev for the rule. Nothing to compile on the robot.
        f"Depends: python3 (>= {python_min}), python3 (<< {python_next}), systemd, udev\n"
        "Section: misc\n"
        "Priority: optional\n"
        "Description: safety supervisor for robots with the SRCS remote\n"
        " srcsd owns the link to the SRCS receiver (VSC), feeds its watchdog, turns\n"
        " silence into a stop, drives the enable lines of the motion controllers and\n"
        " records every stop. With srcsctl, srcs-sim and srcs-exporter.\n"
    )


def maintainer_scripts(debian: Path) -> None:
    for name in ("postinst", "prerm", "postrm"):
        target = debian / name
        shutil.copy2(REPO / "packaging/debian" / name, target)
        target.chmod(0o755)


def md5sums(root: Path) -> str:
    lines = []
    for path in sorted(root.rglob("*")):
        relative = path.relative_to(root)
        if relative.parts[0] == "DEBIAN" or path.is_symlink() or not path.is_file():
            continue
        lines.append(f"{hashlib.md5(path.read_bytes()).hexdigest()}  {relative}\n")  # noqa: S324
    return "".join(lines)


def normalise(root: Path, epoch: int) -> None:
    """Modes and times that do not depend on the build machine's umask or clock."""
    for path in [root, *root.rglob("*")]:
        if not path.is_symlink():
            executable = path.is_dir() or path.stat().st_mode & 0o111
            path.chmod(0o755 if executable else 0o644)
        os.utime(path, (epoch, epoch), follow_symlinks=False)


def source_epoch() -> int:
    if "SOURCE_DATE_EPOCH" in os.environ:
        return int(os.environ["SOURCE_DATE_EPOCH"])
    try:
        return int(run("git", "log", "-1", "--format=%ct").strip())
    except (BuildError, ValueError):
        return 0


def build(arch: str, out: Path, work: Path, wheels: Path = REPO / "build/wheels") -> Path:
    machine = MACHINES.get(arch)
    if machine is None:
        raise BuildError(f"architecture {arch}: not one of {', '.join(MACHINES)}")
    info = project()
    version = str(info["version"])
    scripts = info["scripts"]
    assert isinstance(scripts, dict)
    shutil.rmtree(work, ignore_errors=True)
    root = work / "root"
    site = root / SITE
    site.parent.mkdir(parents=True)
    install_dependencies(work, machine, site, wheels)
    install_program(work, site)
    names = write_environment(root, scripts)
    install_files(root, names)
    epoch = source_epoch()
    normalise(root, epoch)
    compile_modules(root, site)
    debian = root / "DEBIAN"
    debian.mkdir()
    (debian / "control").write_text(control(root, version, arch))
    (debian / "md5sums").write_text(md5sums(root))
    maintainer_scripts(debian)
    normalise(root, epoch)
    out.mkdir(parents=True, exist_ok=True)
    deb = out / f"{PACKAGE}_{version}_{arch}.deb"
    env = {**os.environ, "SOURCE_DATE_EPOCH": str(epoch)}
    result = subprocess.run(
        ["dpkg-deb", "--root-owner-group", "-Zxz", "--build", str(root), str(deb)],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    if result.returncode != 0:
        raise BuildError(f"dpkg-deb failed:\n{result.stderr}")
    return deb


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    default_arch = subprocess.run(
        ["dpkg", "--print-architecture"], capture_output=True, text=True, check=False
    ).stdout.strip()
    parser.add_argument("--arch", default=default_arch, choices=sorted(MACHINES))
    parser.add_argument("--out", type=Path, default=REPO / "dist", help="where the .deb goes")
    parser.add_argument(
        "--work", type=Path, default=REPO / "build/deb", help="scratch (emptied first)"
    )
    parser.add_argument(
        "--fetch",
        action="store_true",
        help="only put the pinned wheels into build/wheels (./dev test does, before its tests "
        "run without a network)",
    )
    args = parser.parse_args()
    try:
        if args.fetch:
            fetch_wheels(MACHINES[args.arch], REPO / "build/wheels")
            return 0
        deb = build(args.arch, args.out.resolve(), args.work.resolve())
    except BuildError as error:
        print(f"build_deb: {error}", file=sys.stderr)
        return 1
    print(deb)
    return 0


if __name__ == "__main__":
    sys.exit(main())

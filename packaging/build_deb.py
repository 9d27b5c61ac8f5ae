"""Build srcs-supervisord_VERSION_ARCH.deb from this repository (``./dev deb``; docs/install.md).

usage: python packaging/build_deb.py [--arch ARCH] [--out DIR] [--work DIR] [--fetch]

The program goes to ``/opt/srcsd`` as a virtual environment with no interpreter of its own:
``bin/python3`` is a link to ``/usr/bin/python3``, ``pyvenv.cfg`` names ``/usr/bin``, and the
pinned dependencies (``requirements/run.txt``, hash-checked) are installed from wheels into
``lib/python3/site-packages``, which ``lib/python3.10`` to ``lib/python3.14`` all point to.
Each compiled extension is there once per Python version (``*.cpython-310-*.so`` beside
``*.cpython-311-*.so`` and so on), so one package serves every Python from Ubuntu 22.04's
3.10 to Ubuntu 26.04's 3.14. The commands in ``bin/`` are launchers that find the environment
from their own location, so the tree runs wherever it is unpacked (docs/install.md "What the
package contains", and why a venv rather than a plain ``--target`` directory: the daemon's tools
start ``sys.executable -m supervisord...``, which must see the same libraries).

The build is reproducible: every time in the package is ``SOURCE_DATE_EPOCH`` (the last
commit's time unless set), nothing of the build machine's paths is kept, and no byte-code is
shipped (postinst compiles for the robot's own Python). Nothing here is compiled: every
dependency is a wheel, the journal is written without libsystemd. Man pages and completion come
from the packaged ``python -m supervisord.cli.reference``; the build fails if that module is
missing. It runs in an environment with requirements/build.txt only (``./dev deb``).
"""

from __future__ import annotations

import argparse
import csv
import filecmp
import gzip
import hashlib
import importlib.metadata
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Collection, Iterator, Mapping
from fnmatch import fnmatchcase
from pathlib import Path

import tomllib
from packaging.requirements import Requirement
from packaging.tags import parse_tag
from packaging.utils import canonicalize_name
from packaging.version import Version

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "srcs-supervisord"
PREFIX = Path("opt/srcsd")
SITE = PREFIX / "lib/python3/site-packages"
DOC = Path("usr/share/doc", PACKAGE)
PYTHONS = ("3.10", "3.11", "3.12", "3.13", "3.14")
"""The Python versions whose extension modules are bundled: Ubuntu 22.04 (3.10), Debian 12
(3.11), Ubuntu 24.04 (3.12), Debian 13 (3.13), Ubuntu 26.04 (3.14)."""
GLIBC_CEILING = 35
"""Wheels are taken for manylinux up to 2.35 only, the oldest C library of the targets (Ubuntu
22.04's 2.35); the package's libc6 dependency is what the chosen wheels' tags need."""
MANYLINUX_LEGACY = {"manylinux1": (2, 5), "manylinux2010": (2, 12), "manylinux2014": (2, 17)}
"""The C library the older manylinux names stand for (PEP 600)."""
NOT_BUNDLED = frozenset({"lz4", "zstandard"})
"""Locked, but left out of the package: the compression libraries ``mcap`` names, compiled
(30 MB for each Python), which its writer imports only for a compressed file; ``srcsctl
replay --mcap`` writes it uncompressed, so the robot's package carries mcap alone and the
export works where the window is (SR-7.15; docs/record.md "Looking at a stop")."""
MACHINES = {"amd64": "x86_64", "arm64": "aarch64"}
"""Debian architecture -> the wheels' machine name."""
LEFT_OUT = {"srcs-ros2", "srcs-fleet-targets", "srcs-fleet-pki"}
"""Console scripts not packaged: the ROS 2 bridge is its own package, run by ROS's Python and
rclpy (``python3-srcs-ros2``, packaging/build_ros2_deb.py; docs/ros2.md "Install"); the fleet's
targets and certificates are the collector's (``srcs-collector``,
packaging/build_collector_deb.py; docs/fleet.md "The collector package"). The fleet stop's
agent, ``srcs-fleet-agent``, is the robot's: packaged with its MQTT client (paho-mqtt, the
``fleet`` extra, locked in requirements/run.txt), its unit and its user, and off until a fleet
enables it (SR-13.13; docs/fleet.md "The agent's unit")."""
SERVICES = ("srcsd", "srcs-exporter", "srcs-fleet-agent")
"""The commands systemd runs, each as its own unit: in /usr/sbin, their pages in section 8."""
MAINTAINER = "srcs-supervisord maintainers <srcs-supervisord@example.com>"
"""The package's Maintainer: fixed here, whoever builds it."""
CHANGELOG = REPO / "packaging/changelog"
COPYRIGHT = REPO / "packaging/copyright"

LAUNCHER = """#!/bin/sh
'''[' "${{0#/}}" != "$0" ']' && '[' ! -L "$0" ']' && exec "${{0%/*}}/python3" "$0" "$@"
exec "$(dirname -- "$(readlink -f -- "$0")")/python3" "$0" "$@"
' '''
# {name}, from the {package} package. The three lines above are shell: they run this file
# with the python3 beside it (a link to /usr/bin/python3 in this virtual environment), so
# the tree works wherever it is; for Python they are a string. Run by its own absolute path
# (the units' ExecStart=), the shell execs at once, with no child: under srcsd@'s SCHED_FIFO
# a readlink or dirname child's exit, and the read of its output, are wakes of a real-time
# process from below that the kernel's rtapp monitors flag (SR-9.8, docs/install.md). Only
# a link (the /usr/sbin ones) or a relative path asks readlink for the real place.
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


def run(*cmd: str | Path, cwd: Path = REPO, env: Mapping[str, str] | None = None) -> str:
    result = subprocess.run(
        [str(c) for c in cmd], cwd=cwd, capture_output=True, text=True, env=env, check=False
    )
    if result.returncode != 0:
        raise BuildError(
            f"{' '.join(str(c) for c in cmd)} failed ({result.returncode}):\n"
            f"{result.stdout[-3000:]}{result.stderr[-3000:]}"
        )
    return result.stdout


def pip(*args: str | Path, env: Mapping[str, str] | None = None) -> None:
    run(sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", *args, env=env)


def project() -> dict[str, object]:
    with (REPO / "pyproject.toml").open("rb") as handle:
        data: dict[str, object] = tomllib.load(handle)["project"]
    return data


# The dependencies, once per Python version, merged into one site-packages.


def marker_environment(version: str, machine: str) -> dict[str, str]:
    """What a requirement's marker sees on a robot with CPython ``version`` on Linux ``machine``
    (its patch level unknown: ``.0``); ``extra`` empty, so optional requirements are out."""
    return {
        "implementation_name": "cpython",
        "implementation_version": f"{version}.0",
        "os_name": "posix",
        "platform_machine": machine,
        "platform_python_implementation": "CPython",
        "platform_release": "",
        "platform_system": "Linux",
        "platform_version": "",
        "python_full_version": f"{version}.0",
        "python_version": version,
        "sys_platform": "linux",
        "extra": "",
    }


def locked() -> Iterator[tuple[Requirement, str]]:
    """requirements/run.txt's entries, in order: each requirement with its options (its
    hashes), for :func:`pinned` to write again."""
    text = (REPO / "requirements/run.txt").read_text().replace("\\\n", " ")
    for entry in text.splitlines():
        line = entry.strip()
        if not line or line.startswith("#"):
            continue
        spec, _, options = line.partition(" --")
        yield Requirement(spec.strip()), options


def pinned(requirement: Requirement, options: str) -> str:
    """One line of a requirement file for pip: the requirement and its options."""
    return f"{requirement} --{options}\n" if options else f"{requirement}\n"


def requirements_for(version: str, machine: str, directory: Path) -> Path:
    """requirements/run.txt for one Python: the entries whose markers hold there, but those
    :data:`NOT_BUNDLED`, markers removed, hashes kept. pip judges a requirement file's markers
    by the Python that runs pip, not by ``--python-version``'s, so it would leave out tomli
    for 3.10 on a 3.11 build."""
    environment = marker_environment(version, machine)
    kept = []
    for requirement, options in locked():
        if requirement.marker is not None and not requirement.marker.evaluate(environment):
            continue
        if canonicalize_name(requirement.name) in NOT_BUNDLED:
            continue
        requirement.marker = None
        kept.append(pinned(requirement, options))
    path = directory / f"requirements-{version}.txt"
    path.write_text("".join(kept))
    return path


def platforms(machine: str) -> list[str]:
    """pip's --platform for every manylinux tag up to the ceiling (pip takes each literally)."""
    tags = [f"manylinux_2_{minor}_{machine}" for minor in range(5, GLIBC_CEILING + 1)]
    tags += [f"{legacy}_{machine}" for legacy in MANYLINUX_LEGACY]
    return [arg for tag in tags for arg in ("--platform", tag)]


def wheel_args(version: str, machine: str, requirements: Path) -> list[str | Path]:
    abi = "cp" + version.replace(".", "")
    return [
        *("--no-deps", "--only-binary=:all:", "--python-version", version),
        *("--implementation", "cp", "--abi", abi, *platforms(machine)),
        *("--require-hashes", "-r", requirements),
    ]


def fetch_wheels(machine: str, wheels: Path) -> None:
    """The pinned wheels for every Python version, in ``wheels``: from there when they are
    all there (the tests build without a network), else downloaded. Hash-checked both ways."""
    with tempfile.TemporaryDirectory(prefix="srcs-deb-") as scratch:
        for version in PYTHONS:
            args = wheel_args(version, machine, requirements_for(version, machine, Path(scratch)))
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


def check_complete(tree: Path, version: str, machine: str) -> None:
    """Every requirement of the program and of each distribution in ``tree``, as it applies on
    this Python, is met there (but :data:`NOT_BUNDLED`). pip checks none of it (--no-deps:
    the lock is the whole set), so a lock that lacks a dependency for some Python would
    otherwise ship a broken package."""
    environment = marker_environment(version, machine)
    distributions = list(importlib.metadata.distributions(path=[str(tree)]))
    installed = {canonicalize_name(d.metadata["Name"]): Version(d.version) for d in distributions}
    own = project()["dependencies"]
    assert isinstance(own, list)
    wanted = [(PACKAGE, str(text)) for text in own]
    wanted += [(d.metadata["Name"], text) for d in distributions for text in d.requires or []]
    for who, text in wanted:
        requirement = Requirement(text)
        if requirement.marker is not None and not requirement.marker.evaluate(environment):
            continue
        if canonicalize_name(requirement.name) in NOT_BUNDLED:
            continue
        have = installed.get(canonicalize_name(requirement.name))
        if have is None or not requirement.specifier.contains(have, prereleases=True):
            raise BuildError(
                f"Python {version}: {who} needs {requirement}, requirements/run.txt gives "
                f"{have or 'nothing'}"
            )


def glibc_needed(tree: Path) -> tuple[int, int]:
    """The newest C library the wheels installed in ``tree`` need. A wheel runs on any of its
    platform tags, so each needs the oldest its tags name (manylinux_2_17 and manylinux_2_28:
    2.17); a pure-Python wheel needs none."""
    needed = (0, 0)
    for wheel in sorted(tree.glob("*.dist-info/WHEEL")):
        lines = wheel.read_text().splitlines()
        tags = [
            tag for line in lines if line.startswith("Tag:") for tag in parse_tag(line[4:].strip())
        ]
        versions = []
        for platform in sorted({tag.platform for tag in tags} - {"any"}):
            numbered = re.match(r"manylinux_(\d+)_(\d+)_", platform)
            if numbered is not None:
                versions.append((int(numbered[1]), int(numbered[2])))
            elif platform.split("_")[0] in MANYLINUX_LEGACY:
                versions.append(MANYLINUX_LEGACY[platform.split("_")[0]])
            else:
                raise BuildError(f"{wheel.parent.name}: {platform} names no glibc version")
        if versions:
            needed = max(needed, min(versions))
    return needed


def merge(trees: Mapping[str, Path], site: Path) -> None:
    """One site-packages from the per-version trees. A file in several trees must be the same
    in each: only extension modules differ by version, and their names carry it
    (``_ext.cpython-311-x86_64-linux-gnu.so``). A distribution that only some versions need
    (tomli, below 3.11) is there for all; nothing imports it elsewhere. A dist-info's WHEEL and
    RECORD name each version's tags and files: their lines are merged, in order."""
    merged: dict[Path, list[str]] = {}
    for version, tree in trees.items():
        for path in sorted(tree.rglob("*")):
            relative = path.relative_to(tree)
            target = site / relative
            if path.is_dir():
                continue
            if relative.parts[0].endswith(".dist-info") and relative.name in ("WHEEL", "RECORD"):
                lines = merged.setdefault(relative, [])
                lines += [line for line in path.read_text().splitlines() if line not in lines]
            elif not target.exists():
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(path, target)
            elif not filecmp.cmp(path, target, shallow=False):
                raise BuildError(
                    f"{relative}: the wheels for Python {version} and an earlier one differ in "
                    "more than their extension modules; one shared site-packages cannot hold them"
                )
    for relative, lines in merged.items():
        (site / relative).write_text("".join(f"{line}\n" for line in lines))


def install_dependencies(work: Path, machine: str, site: Path, wheels: Path) -> tuple[int, int]:
    """requirements/run.txt, hash-checked, once per Python version into a tree of its own, each
    checked complete, then merged into ``site``. Returns the C library the wheels need."""
    fetch_wheels(machine, wheels)
    trees = {}
    glibc = (0, 0)
    for version in PYTHONS:
        tree = work / f"deps-{version}"
        requirements = requirements_for(version, machine, work)
        pip(
            "install",
            *("--target", tree, "--no-compile", "--no-index", "--find-links", wheels),
            *wheel_args(version, machine, requirements),
        )
        # The dependencies' console scripts (python-can's, pyserial's): nothing here runs
        # them, and pip wrote the build's own Python into their #! lines.
        shutil.rmtree(tree / "bin", ignore_errors=True)
        check_complete(tree, version, machine)
        glibc = max(glibc, glibc_needed(tree))
        trees[version] = tree
    site.mkdir(parents=True)
    merge(trees, site)
    return glibc


def install_program(work: Path, site: Path, env: Mapping[str, str]) -> None:
    """This repository as a wheel (no dependencies: they are above), built with the zip times
    of ``SOURCE_DATE_EPOCH`` and installed by name, so that pip records no local path."""
    source = work / "src"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, source / name)
    shutil.copytree(
        REPO / "supervisord",
        source / "supervisord",
        ignore=shutil.ignore_patterns("__pycache__", "*.pyc"),
    )
    pip("wheel", "--no-deps", "--no-build-isolation", "-w", work / "wheel", source, env=env)
    own = work / "own"
    version = str(project()["version"])
    pip(
        "install",
        *("--target", own, "--no-deps", "--no-compile", "--no-index"),
        *("--find-links", work / "wheel", f"{PACKAGE}=={version}"),
    )
    shutil.rmtree(own / "bin")  # pip's scripts; the launchers are written below
    for path in own.iterdir():
        shutil.move(path, site / path.name)


def tidy_records(site: Path) -> None:
    """Each RECORD lists the files shipped and no other: not the console scripts left out."""
    for record in sorted(site.glob("*.dist-info/RECORD")):
        lines = record.read_text().splitlines()
        kept = [line for line in lines if (site / next(csv.reader([line]))[0]).is_file()]
        record.write_text("".join(f"{line}\n" for line in kept))


# The copyright file and the changelog, checked against what is bundled.


def deb822(text: str) -> list[dict[str, str]]:
    """The paragraphs of a Debian control-style file: field -> value (continuations joined
    with newlines, leading space kept)."""
    paragraphs: list[dict[str, str]] = []
    current: dict[str, str] = {}
    field = ""
    for line in [*text.splitlines(), ""]:
        if not line.strip():
            if current:
                paragraphs.append(current)
            current, field = {}, ""
        elif line[0] in " \t" and field:
            current[field] += "\n" + line
        elif not line.startswith("#"):
            field, _, value = line.partition(":")
            current[field] = value.strip()
    return paragraphs


def declared_licence(distribution: importlib.metadata.Distribution) -> str:
    """The licence a distribution's metadata declares: License-Expression, else License's first
    line, else its licence classifiers."""
    metadata = distribution.metadata
    for field in ("License-Expression", "License"):
        values = metadata.get_all(field) or []
        if values and str(values[0]).strip():
            return str(values[0]).strip().splitlines()[0]
    classifiers = metadata.get_all("Classifier") or []
    return "; ".join(str(c) for c in classifiers if str(c).startswith("License ::"))


def check_copyright(site: Path, text: str, where: Path = SITE) -> None:
    """The copyright file ``text`` (machine-readable, DEP-5) covers every distribution bundled
    in ``site`` (``where`` in the package: the robot's or the collector's): each of its files
    is matched (the last matching paragraph wins) by a paragraph whose ``Distribution`` names
    it and whose ``Distribution-License`` is what its metadata declares. A dependency added or
    relicensed fails the build until the file says so."""
    paragraphs = [p for p in deb822(text) if "Files" in p]
    for distribution in importlib.metadata.distributions(path=[str(site)]):
        name = distribution.metadata["Name"]
        if canonicalize_name(name) == PACKAGE:
            continue
        licence = declared_licence(distribution)
        for file in distribution.files or []:
            path = (where / str(file)).as_posix()
            matching = [
                p for p in paragraphs if any(fnmatchcase(path, f) for f in p["Files"].split())
            ]
            paragraph = matching[-1] if matching else {}
            if paragraph.get("Distribution") != name:
                raise BuildError(
                    f"packaging/copyright: {path} ({name} {distribution.version}) is not in a "
                    f"paragraph with 'Distribution: {name}'"
                )
            if paragraph.get("Distribution-License") != licence:
                raise BuildError(
                    f"packaging/copyright: {name}'s metadata declares the licence "
                    f"'{licence}', its paragraph says '{paragraph.get('Distribution-License')}'"
                )


def changelog_version() -> str:
    """The version of packaging/changelog's top entry (Debian changelog format)."""
    first = CHANGELOG.read_text().splitlines()[0]
    entry = re.fullmatch(rf"{PACKAGE} \(([^()\s]+)\) [a-z][\w-]*; urgency=\w+", first)
    if entry is None:
        raise BuildError(f"packaging/changelog: '{first}' is not a Debian changelog entry")
    return entry[1]


# The package's tree.


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
        where = "usr/sbin" if name in SERVICES else "usr/bin"
        link = root / where / name
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(f"/{PREFIX}/bin/{name}")
    return names


def gzip_file(source: Path, target: Path) -> None:
    """``gzip -9n``: no name and no time in the header, so the same text gives the same bytes."""
    target.parent.mkdir(parents=True, exist_ok=True)
    with (
        source.open("rb") as raw,
        target.open("wb") as out,
        gzip.GzipFile(filename="", mode="wb", compresslevel=9, fileobj=out, mtime=0) as packed,
    ):
        shutil.copyfileobj(raw, packed)


def generator_path(work: Path, machine: str, site: Path, wheels: Path) -> str:
    """The ``PYTHONPATH`` the man pages and completion are generated with: the packaged tree.
    For a package of another machine (arm64, built on amd64) this machine's own dependencies
    come first: the build's Python cannot load the package's compiled modules, and the
    configuration's page imports gpiod's through the outputs' schema (srcsd.toml(5))."""
    here = os.uname().machine
    if machine == here:
        return str(site)
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    native = work / "native"
    native.mkdir()
    fetch_wheels(here, wheels)
    requirements = requirements_for(version, here, native)
    pip(
        "install",
        *("--target", native / "site", "--no-compile", "--no-index", "--find-links", wheels),
        *wheel_args(version, here, requirements),
    )
    return f"{native / 'site'}{os.pathsep}{site}"


def install_files(root: Path, names: list[str], env: Mapping[str, str], generators: str) -> None:
    """Units, sysusers, tmpfiles, udev; docs, examples, copyright, changelog and the lintian
    overrides; man pages and completion, generated with ``generators`` on the path
    (:func:`generator_path`)."""
    units = REPO / "units"
    put: list[tuple[Path, Path]] = [
        (units / "srcsd@.service", Path("usr/lib/systemd/system/srcsd@.service")),
        (units / "srcs-exporter@.service", Path("usr/lib/systemd/system/srcs-exporter@.service")),
        # The fleet stop's agent and its user: installed, never enabled by the package; a
        # fleet turns it on per robot (SR-13.13; docs/fleet.md "The agent's unit").
        (
            units / "srcs-fleet-agent@.service",
            Path("usr/lib/systemd/system/srcs-fleet-agent@.service"),
        ),
        # The kernel judge's counter: installed, never enabled by the package; an integrator
        # turns it on for a kernel built with the rtapp monitors (SR-9.9;
        # docs/kernel-judge.md).
        (units / "srcs-rv.service", Path("usr/lib/systemd/system/srcs-rv.service")),
        (units / "srcsd.sysusers.conf", Path("usr/lib/sysusers.d/srcsd.conf")),
        (
            units / "srcs-fleet-agent.sysusers.conf",
            Path("usr/lib/sysusers.d/srcs-fleet-agent.conf"),
        ),
        (units / "srcsd.tmpfiles.conf", Path("usr/lib/tmpfiles.d/srcsd.conf")),
        (units / "60-srcs.rules", Path("usr/lib/udev/rules.d/60-srcs.rules")),
        (REPO / "packaging/lintian-overrides", Path("usr/share/lintian/overrides", PACKAGE)),
    ]
    put += [(REPO / "README.md", DOC / "README.md")]
    put += [(COPYRIGHT, DOC / "copyright")]
    put += [(path, DOC / "docs" / path.name) for path in sorted((REPO / "docs").glob("*.md"))]
    put += [(path, DOC / "examples" / path.name) for path in sorted((REPO / "config").glob("*"))]
    put += [(units / "srcs-ros2@.service", DOC / "examples/srcs-ros2@.service")]
    # The motion service example, its unit and its user, as docs/bringup.md installs them
    # from here: a team wires its robot from the package, not from a checkout (SR-8.10).
    put += [
        (REPO / "examples" / path, DOC / "examples" / Path(path).name)
        for path in (
            "motion/robot_motion.py",
            "systemd/robot-motion@.service",
            "systemd/robot-motion.conf",
        )
    ]
    # The fleet's drop-ins, off until installed (docs/fleet.md "Only the supervisor's
    # entries leave the robot", SR-13.11).
    put += [
        (units / name, DOC / "examples" / name)
        for name in ("srcsd-log-namespace.conf", "systemd-journal-upload-srcs.conf")
    ]
    for source, target in put:
        if source.is_dir():
            shutil.copytree(source, root / target)
        else:
            (root / target).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, root / target)
    # A native package (its version has no Debian revision): changelog.gz, not changelog.Debian.gz.
    gzip_file(CHANGELOG, root / DOC / "changelog.gz")

    work = root.parent
    generated = work / "generated"
    # The packaged program generates them from its parsers (docs/srcsctl.md), with its own
    # version and dependencies: its site-packages first on the path (from the work directory,
    # not this repository, which -m would put first). The build's Python must be one the
    # package supports; the build environment adds only the generators (shtab,
    # argparse-manpage). The pages' date is SOURCE_DATE_EPOCH's. No byte-code is written into
    # the tree (it would name the work directory).
    packaged = {**env, "PYTHONPATH": generators, "PYTHONDONTWRITEBYTECODE": "1"}
    for kind in ("man", "completion"):
        try:
            run(
                sys.executable,
                "-m",
                "supervisord.cli.reference",
                kind,
                generated / kind,
                "--only",
                *names,
                cwd=work,
                env=packaged,
            )
        except BuildError as error:
            raise BuildError(f"man pages and completion could not be generated: {error}") from None
    install_manuals(generated, root, names)


def install_manuals(generated: Path, root: Path, names: Collection[str]) -> None:
    """The generated man pages (gzipped) and bash completions of ``names`` into ``root``;
    refused when a command has either missing, or srcsd its configuration file's page. The
    robot's and the collector's package."""
    for page in sorted((generated / "man").iterdir()):
        section = page.suffix.lstrip(".")
        if section.isdigit():
            gzip_file(page, root / f"usr/share/man/man{section}/{page.name}.gz")
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
    # The daemon's configuration file has its page where the daemon is: srcsd.toml(5),
    # generated from the file's schema (SR-11.2; docs/configuration.md "The man page").
    if "srcsd" in names and not (root / "usr/share/man/man5/srcsd.toml.5.gz").is_file():
        raise BuildError("no man page for the configuration file, srcsd.toml(5)")


def control(root: Path, version: str, arch: str, glibc: tuple[int, int]) -> str:
    size = sum(p.lstat().st_size for p in root.rglob("*") if not p.is_dir()) // 1024 + 1
    python_min, python_next = PYTHONS[0], f"3.{int(PYTHONS[-1].split('.')[1]) + 1}"
    libc = f", libc6 (>= {glibc[0]}.{glibc[1]})" if glibc > (0, 0) else ""
    return (
        f"Package: {PACKAGE}\n"
        f"Version: {version}\n"
        f"Architecture: {arch}\n"
        f"Maintainer: {MAINTAINER}\n"
        f"Installed-Size: {size}\n"
        # The interpreter the venv links to, a version whose extension modules are bundled;
        # the C library the bundled wheels' manylinux tags need; systemd for the units and
        # for systemd-sysusers and systemd-tmpfiles, which the postinst runs even where no
        # systemd runs (a container). udev only applies the rule: a container has none and
        # needs none (the postinst skips udevadm without it), so a Recommends (SR-0.4,
        # docs/containers.md "The package's dependencies"). bash-completion loads the
        # completion that offers the robots of /etc/srcs for -R: a minimal system lacks it
        # (SR-0.2). Nothing to compile.
        f"Depends: python3 (>= {python_min}), python3 (<< {python_next}){libc}, systemd\n"
        "Recommends: udev, bash-completion\n"
        "Section: misc\n"
        "Priority: optional\n"
        "Description: safety supervisor for robots with the SRCS remote\n"
        " srcsd owns the link to the SRCS receiver (VSC), feeds its watchdog, turns\n"
        " silence into a stop, drives the enable lines of the motion controllers and\n"
        " records every stop. With srcsctl, srcs-sim, srcs-exporter and the fleet\n"
        " stop's agent, srcs-fleet-agent (not enabled until a fleet turns it on).\n"
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
    if changelog_version() != version:
        raise BuildError(
            f"packaging/changelog's top entry is {changelog_version()}, pyproject.toml's version "
            f"is {version}: add an entry for it"
        )
    scripts = info["scripts"]
    assert isinstance(scripts, dict)
    epoch = source_epoch()
    env = {**os.environ, "SOURCE_DATE_EPOCH": str(epoch)}
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    root = work / "root"
    site = root / SITE
    glibc = install_dependencies(work, machine, site, wheels)
    install_program(work, site, env)
    tidy_records(site)
    check_copyright(site, COPYRIGHT.read_text())
    names = write_environment(root, scripts)
    install_files(root, names, env, generator_path(work, machine, site, wheels))
    debian = root / "DEBIAN"
    debian.mkdir()
    (debian / "control").write_text(control(root, version, arch, glibc))
    (debian / "md5sums").write_text(md5sums(root))
    maintainer_scripts(debian)
    normalise(root, epoch)
    return dpkg_build(root, out / f"{PACKAGE}_{version}_{arch}.deb", env)


def dpkg_build(root: Path, deb: Path, env: dict[str, str]) -> Path:
    """``deb`` built from the tree at ``root`` (its ``DEBIAN`` written, its times normalised),
    refused when byte-code slipped in. The robot's and the collector's package alike."""
    if compiled := [str(p.relative_to(root)) for p in root.rglob("*.pyc")]:
        raise BuildError(f"byte-code in the package (postinst compiles it): {compiled[:3]}")
    deb.parent.mkdir(parents=True, exist_ok=True)
    # xz at level 3, not dpkg-deb's 6: a tenth larger, and about five times faster on a busy
    # two-core machine (the tests build the package twice). The same bytes whatever the number
    # of threads xz uses.
    result = subprocess.run(
        ["dpkg-deb", "--root-owner-group", "-Zxz", "-z3", "--build", str(root), str(deb)],
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

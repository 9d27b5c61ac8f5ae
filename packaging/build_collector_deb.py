"""Build ``srcs-collector_VERSION_all.deb``, the fleet collector's package (``./dev deb
--collector``; docs/fleet.md "The collector package", SR-13.10).

usage: python packaging/build_collector_deb.py [--out DIR] [--work DIR]

A collector is no robot: it reads the fleet's records and alerts on its metrics. So the
package holds the reading tools and the fleet's configuration, and nothing of the robot's:

- ``/opt/srcs-collector``: the program's own modules in a virtual environment on the system's
  ``python3``, as the robot's ``/opt/srcsd`` (packaging/build_deb.py), with one bundled
  dependency: ``mcap`` (:data:`BUNDLED`), pure Python, from requirements/run.txt with its hash,
  so that ``fleet replay --mcap`` writes the file where the collector's windows are
  (SR-7.15). The export writes it uncompressed, so mcap's compression libraries (lz4,
  zstandard: compiled) stay out, as in the robot's package; ``srcsctl`` and the fleet's tools
  need nothing else (pyserial, python-can, gpiod, prometheus-client are the daemon's, the
  simulator's and the exporter's). Hence architecture ``all``, which the build checks: a
  bundled wheel with a compiled part is refused.
  Commands: ``srcsctl`` (``fleet``), ``srcs-fleet-targets`` and ``srcs-fleet-pki``, with their
  man pages and completion.
- systemd-journal-remote's drop-in (``journal-remote.conf.d``), the retention's timer, the
  targets' watcher, drop-ins that point Debian's Prometheus and Alertmanager at the fleet's
  files; ``/etc/srcs-collector/`` (conffiles): ``prometheus.yml``, ``alertmanager.yml``, the
  list of robots; the alert rules and dashboard in ``/usr/share/srcs-collector``.
- No daemon users, no ``srcsd@`` or ``srcs-exporter@`` unit, no udev rule: it depends on
  ``systemd-journal-remote`` and ``openssl``, not on ``udev`` nor ``srcs-supervisord``, with
  which it conflicts (both ship ``srcsctl``; a robot's has ``fleet`` too).

Reproducible as the robot's: every time is ``SOURCE_DATE_EPOCH``, no byte-code (postinst
compiles for the machine's python3). Runs in the ``./dev deb`` environment.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
from pathlib import Path

from packaging.tags import parse_tag
from packaging.utils import canonicalize_name

sys.path.insert(0, str(Path(__file__).resolve().parent))

from build_deb import (
    CHANGELOG,
    LAUNCHER,
    MAINTAINER,
    PYTHONS,
    PYVENV_CFG,
    REPO,
    BuildError,
    changelog_version,
    check_copyright,
    dpkg_build,
    gzip_file,
    install_manuals,
    install_program,
    locked,
    md5sums,
    normalise,
    pinned,
    pip,
    project,
    run,
    source_epoch,
    tidy_records,
)

PACKAGE = "srcs-collector"
PREFIX = Path("opt/srcs-collector")
SITE = PREFIX / "lib/python3/site-packages"
DOC = Path("usr/share/doc", PACKAGE)
SHARE = Path("usr/share", PACKAGE)
HERE = REPO / "packaging/collector"
WHEELS = REPO / "build/wheels"
"""Where the robot's build keeps the pinned wheels (``./dev test`` fills it before its tests
run without a network); the collector's are taken from there first."""
BUNDLED = frozenset({"mcap"})
"""The locked distributions the collector carries: ``mcap`` for ``fleet replay --mcap``, so
the MCAP file is written where the windows are (SR-7.15). Pure Python only (architecture
``all``); not the compression libraries it names, which an uncompressed file does not use."""
COMMANDS = {"srcsctl": "usr/bin", "srcs-fleet-targets": "usr/sbin", "srcs-fleet-pki": "usr/sbin"}
"""The collector's commands and where their links go (admin tools in /usr/sbin, section 8)."""
CONFFILES = ("prometheus.yml", "alertmanager.yml", "robots")
"""/etc/srcs-collector's files: the administrator edits them, dpkg keeps the edits."""
SYSTEMD = Path("usr/lib/systemd/system")
FILES = {
    "journal-remote.conf": Path("usr/lib/systemd/journal-remote.conf.d/50-srcs-collector.conf"),
    "srcs-collector-retention.service": SYSTEMD / "srcs-collector-retention.service",
    "srcs-collector-retention.timer": SYSTEMD / "srcs-collector-retention.timer",
    "srcs-collector-targets.path": SYSTEMD / "srcs-collector-targets.path",
    "srcs-collector-targets.service": SYSTEMD / "srcs-collector-targets.service",
    "prometheus.conf": SYSTEMD / "prometheus.service.d/srcs-collector.conf",
    "alertmanager.conf": SYSTEMD / "prometheus-alertmanager.service.d/srcs-collector.conf",
    "lintian-overrides": Path("usr/share/lintian/overrides", PACKAGE),
    "copyright": DOC / "copyright",
    **{name: Path("etc/srcs-collector", name) for name in CONFFILES},
}
"""packaging/collector's files and where each goes."""
SHARED = {
    REPO / "config/prometheus/srcs-alerts.yml": SHARE / "srcs-alerts.yml",
    REPO / "config/prometheus/srcs-dashboard.json": SHARE / "srcs-dashboard.json",
    REPO / "README.md": DOC / "README.md",
}


def write_environment(root: Path, scripts: dict[str, str]) -> None:
    """pyvenv.cfg, the interpreter links, lib/python3.X -> python3, the launchers and their
    links on the path."""
    prefix = root / PREFIX
    (prefix / "pyvenv.cfg").write_text(PYVENV_CFG)
    bin_dir = prefix / "bin"
    bin_dir.mkdir(parents=True)
    (bin_dir / "python3").symlink_to("/usr/bin/python3")
    (bin_dir / "python").symlink_to("python3")
    for version in PYTHONS:
        (prefix / f"lib/python{version}").symlink_to("python3")
    for name, where in COMMANDS.items():
        module, function = scripts[name].split("#")[0].strip().split(":")
        launcher = bin_dir / name
        launcher.write_text(
            LAUNCHER.format(name=name, package=PACKAGE, module=module, function=function)
        )
        launcher.chmod(0o755)
        link = root / where / name
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(f"/{PREFIX}/bin/{name}")


def bundled_requirements(directory: Path) -> Path:
    """requirements/run.txt's entries for :data:`BUNDLED`, hashes kept, markers dropped (they
    hold on every Python the package serves: the build refuses a compiled wheel below)."""
    kept = []
    names = set()
    for requirement, options in locked():
        name = canonicalize_name(requirement.name)
        if name in BUNDLED:
            requirement.marker = None
            kept.append(pinned(requirement, options))
            names.add(name)
    if names != BUNDLED:
        raise BuildError(f"requirements/run.txt pins none of {sorted(BUNDLED - names)}")
    path = directory / "bundled.txt"
    path.write_text("".join(kept))
    return path


def install_bundled(work: Path, site: Path, wheels: Path = WHEELS) -> None:
    """:data:`BUNDLED` from the lock, hash-checked, into ``site``: the wheels from ``wheels``
    when there (the tests build without a network), else downloaded. Refused when a wheel is
    anything but pure Python (its tags: ``none`` ABI, ``any`` platform), which an
    architecture-``all`` package cannot carry."""
    tree = work / "bundled"
    with tempfile.TemporaryDirectory(prefix="srcs-collector-") as scratch:
        requirements = bundled_requirements(Path(scratch))
        args = ("--no-deps", "--only-binary=:all:", "--require-hashes", "-r", requirements)
        try:
            pip("download", "--no-index", "--find-links", wheels, "--dest", wheels, *args)
        except BuildError:
            try:
                pip("download", "--dest", wheels, *args)
            except BuildError as error:
                raise BuildError(f"the collector's {sorted(BUNDLED)}: {error}") from None
        pip(
            "install",
            *("--target", tree, "--no-compile", "--no-index", "--find-links", wheels),
            *args,
        )
    shutil.rmtree(tree / "bin", ignore_errors=True)
    for wheel in sorted(tree.glob("*.dist-info/WHEEL")):
        lines = wheel.read_text().splitlines()
        tags = [t for line in lines if line.startswith("Tag:") for t in parse_tag(line[4:].strip())]
        if not tags or any(t.abi != "none" or t.platform != "any" for t in tags):
            raise BuildError(f"{wheel.parent.name} is not pure Python: {sorted(map(str, tags))}")
    for path in sorted(tree.iterdir()):
        shutil.move(path, site / path.name)


def install_files(root: Path, env: dict[str, str]) -> None:
    """The collector's configuration and units, the rules, the docs, man pages, completion."""
    for name, target in FILES.items():
        (root / target).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(HERE / name, root / target)
    (root / "var/lib/srcs-collector/targets").mkdir(parents=True)
    for source, target in SHARED.items():
        (root / target).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(source, root / target)
    for path in sorted((REPO / "docs").glob("*.md")):
        (root / DOC / "docs").mkdir(parents=True, exist_ok=True)
        shutil.copy2(path, root / DOC / "docs" / path.name)
    gzip_file(CHANGELOG, root / DOC / "changelog.gz")
    # The man pages and completion of the three commands, from their parsers, with the
    # packaged modules first on the path (docs/srcsctl.md "Man pages and completion").
    generated = root.parent / "generated"
    packaged = {**env, "PYTHONPATH": str(root / SITE), "PYTHONDONTWRITEBYTECODE": "1"}
    for kind in ("man", "completion"):
        try:
            run(
                sys.executable, "-m", "supervisord.cli.reference", kind, generated / kind,
                "--only", *COMMANDS, cwd=root.parent, env=packaged,
            )  # fmt: skip
        except BuildError as error:
            raise BuildError(f"man pages and completion could not be generated: {error}") from None
    install_manuals(generated, root, COMMANDS)


def control(root: Path, version: str) -> str:
    size = sum(p.lstat().st_size for p in root.rglob("*") if not p.is_dir()) // 1024 + 1
    python_next = f"3.{int(PYTHONS[-1].split('.')[1]) + 1}"
    return (
        f"Package: {PACKAGE}\n"
        "Source: srcs-supervisord\n"
        f"Version: {version}\n"
        "Architecture: all\n"
        f"Maintainer: {MAINTAINER}\n"
        f"Installed-Size: {size}\n"
        # The receiver whose configuration this is, and openssl for srcs-fleet-pki; no udev,
        # no srcs-supervisord: a collector is no robot.
        f"Depends: python3 (>= {PYTHONS[0]}), python3 (<< {python_next}), "
        "systemd-journal-remote, openssl\n"
        "Recommends: prometheus, prometheus-alertmanager\n"
        # Both ship /usr/bin/srcsctl; the robot's has fleet too.
        "Conflicts: srcs-supervisord\n"
        "Section: misc\n"
        "Priority: optional\n"
        "Description: fleet collector for robots with the SRCS safety supervisor\n"
        " The reading tools and the configuration of a fleet's collector: srcsctl\n"
        " fleet over systemd-journal-remote's journal of the robots' stop records,\n"
        " the receiver's configuration and retention, Prometheus's rules and\n"
        " generated targets, Alertmanager's routes by robot, and the certificates.\n"
    )


def build(out: Path, work: Path) -> Path:
    info = project()
    version = str(info["version"])
    if changelog_version() != version:
        raise BuildError(f"packaging/changelog's top entry is not pyproject.toml's {version}")
    scripts = info["scripts"]
    assert isinstance(scripts, dict)
    epoch = source_epoch()
    env = {**os.environ, "SOURCE_DATE_EPOCH": str(epoch)}
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    root = work / "root"
    site = root / SITE
    site.mkdir(parents=True)
    install_bundled(work, site)
    install_program(work, site, env)
    tidy_records(site)
    check_copyright(site, (HERE / "copyright").read_text(), SITE)
    write_environment(root, scripts)
    install_files(root, env)
    debian = root / "DEBIAN"
    debian.mkdir()
    (debian / "control").write_text(control(root, version))
    (debian / "conffiles").write_text("".join(f"/etc/srcs-collector/{n}\n" for n in CONFFILES))
    (debian / "md5sums").write_text(md5sums(root))
    for name in ("postinst", "prerm", "postrm"):
        shutil.copy2(HERE / name, debian / name)
    normalise(root, epoch)
    for name in ("postinst", "prerm", "postrm"):
        (debian / name).chmod(0o755)
    return dpkg_build(root, out / f"{PACKAGE}_{version}_all.deb", env)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=REPO / "dist", help="where the .deb goes")
    parser.add_argument(
        "--work", type=Path, default=REPO / "build/deb-collector", help="scratch (emptied first)"
    )
    args = parser.parse_args()
    try:
        deb = build(args.out.resolve(), args.work.resolve())
    except BuildError as error:
        print(f"build_collector_deb: {error}", file=sys.stderr)
        return 1
    print(deb)
    return 0


if __name__ == "__main__":
    sys.exit(main())

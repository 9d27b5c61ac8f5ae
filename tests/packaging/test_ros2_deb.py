"""The ROS 2 bridge's Debian package and wheel (packaging/build_ros2_deb.py, docs/ros2.md
"Install"): ``python3-srcs-ros2``, architecture all, depending on python3 alone, the bridge and
the client library's named set in ``/usr/lib/python3/dist-packages`` and a launcher run by
``/usr/bin/python3``; nothing of the daemon, nothing of the build machine, the same bytes
twice. Its tree is run unpacked, never installed on this machine: the launcher with Debian's
own python3, the modules with the ROS 2 Jazzy wheels (and the bridge against the real
``srcsd``: tests/ros2/test_packaged_bridge.py)."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from supervisord.config import toml
from tests.ros2.test_imports import (
    BRIDGE_MODULES,
    CLIENT_MODULES,
    DAEMON_DEPENDENCIES,
    PROBE,
)

ROOT = Path(__file__).resolve().parents[2]
SITE = "/usr/lib/python3/dist-packages"
DOC = "/usr/share/doc/python3-srcs-ros2"
MODULES = CLIENT_MODULES | BRIDGE_MODULES | {"supervisord.ros2.node"}
SYSTEM_PYTHON = Path("/usr/bin/python3")


def _version() -> str:
    with (ROOT / "pyproject.toml").open("rb") as handle:
        return str(toml.load(handle)["project"]["version"])


def _module_file(name: str) -> str:
    path = name.replace(".", "/")
    return f"{path}/__init__.py" if (ROOT / path).is_dir() else f"{path}.py"


def build_packages(out: Path, env: dict[str, str] | None = None) -> tuple[Path, Path]:
    """The .deb and the wheel, built from this tree into ``out`` (in ``env`` when given)."""
    result = subprocess.run(
        [sys.executable, "packaging/build_ros2_deb.py", "--out", out / "dist", "--work", out / "w"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    deb, wheel = result.stdout.split()
    return Path(deb), Path(wheel)


@pytest.fixture(scope="session")
def built(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The .deb and the wheel built from this tree, once per session."""
    if shutil.which("dpkg-deb") is None:
        pytest.fail("dpkg-deb is missing: the package cannot be built or checked")
    return build_packages(tmp_path_factory.mktemp("ros2-deb"))


@pytest.fixture(scope="session")
def deb(built: tuple[Path, Path]) -> Path:
    return built[0]


@pytest.fixture(scope="session")
def listing(deb: Path) -> dict[str, str]:
    """``dpkg-deb -c``: each path (without the leading ``.``) and its line."""
    lines = subprocess.run(
        ["dpkg-deb", "-c", str(deb)], capture_output=True, text=True, check=True
    ).stdout.splitlines()
    return {line.split(None, 5)[5].removeprefix(".").rstrip("/") or "/": line for line in lines}


@pytest.fixture(scope="session")
def unpacked(deb: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The package's files unpacked into a directory (``dpkg-deb -x``), not installed."""
    return unpack(deb, tmp_path_factory.mktemp("ros2-unpacked"))


def unpack(deb: Path, root: Path) -> Path:
    """``dpkg-deb -x`` and ``-e`` into ``root``."""
    subprocess.run(["dpkg-deb", "-x", str(deb), str(root)], check=True)
    subprocess.run(["dpkg-deb", "-e", str(deb), str(root / "DEBIAN")], check=True)
    return root


def field(deb: Path, name: str) -> str:
    return subprocess.run(
        ["dpkg-deb", "-f", str(deb), name], capture_output=True, text=True, check=True
    ).stdout.strip()


def environment(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    return {**env, **extra}


def test_name_architecture_and_the_one_dependency(deb: Path) -> None:
    """``python3-srcs-ros2_<version>_all.deb``, srcs-supervisord's version, architecture all,
    depending on ``python3 (>= 3.10)`` and nothing else: the ROS packages come from ROS."""
    assert deb.name == f"python3-srcs-ros2_{_version()}_all.deb"
    assert field(deb, "Package") == "python3-srcs-ros2"
    assert field(deb, "Version") == _version()
    assert field(deb, "Architecture") == "all"
    assert field(deb, "Depends") == "python3 (>= 3.10)"
    for name in ("Pre-Depends", "Recommends", "Conflicts", "Breaks", "Replaces"):
        assert not field(deb, name), name


def test_files_are_the_bridge_and_the_client_set(listing: dict[str, str]) -> None:
    """The launcher, the modules the bridge loads (no more: nothing of the daemon), their
    metadata and the docs; every file root's, nothing in /etc, no maintainer script."""
    files = {path for path, line in listing.items() if not line.startswith("d")}
    expected = {f"{SITE}/{_module_file(name)}" for name in MODULES}
    expected |= {f"{SITE}/supervisord/py.typed", "/usr/bin/srcs-ros2"}
    info = f"{SITE}/srcs_ros2-{_version()}.dist-info"
    expected |= {f"{info}/{name}" for name in ("METADATA", "WHEEL", "entry_points.txt")}
    expected |= {f"{info}/top_level.txt"}
    expected |= {f"{DOC}/copyright", f"{DOC}/ros2.md"}
    examples = ("srcs-ros2@.service", "srcs_bridge.launch.py", "srcs_bridge.yaml")
    expected |= {f"{DOC}/examples/{name}" for name in examples}
    assert files == expected, sorted(files ^ expected)
    for path, line in listing.items():
        assert " root/root " in line, line
        mode = line.split()[0]
        executable = line.startswith("d") or path == "/usr/bin/srcs-ros2"
        assert mode[1:] == ("rwxr-xr-x" if executable else "rw-r--r--"), line


def test_the_maintainer_is_the_projects_one_address(deb: Path) -> None:
    """SR-0.2: the bridge's Maintainer is the one the supervisor's package and its changelog
    name (one address for the project, written in ros2/package.xml for the bridge)."""
    control = subprocess.run(
        ["dpkg-deb", "-f", str(deb), "Maintainer"], capture_output=True, text=True, check=True
    ).stdout.strip()
    changelog = (ROOT / "packaging/changelog").read_text()
    signed = next(line for line in changelog.splitlines() if line.startswith(" -- "))
    assert signed.startswith(f" -- {control}  "), (control, signed)


def test_control_holds_no_maintainer_script(unpacked: Path) -> None:
    """Nothing runs at install or removal: the control archive is the control file and the
    checksums."""
    assert {p.name for p in (unpacked / "DEBIAN").iterdir()} == {"control", "md5sums"}


def test_the_wheel_carries_what_the_package_does(built: tuple[Path, Path], unpacked: Path) -> None:
    """The wheel beside the package holds the same modules, byte for byte, requires nothing
    from pip (rclpy comes from ROS) and carries the ament index entry and package.xml."""
    _, wheel = built
    assert wheel.name == f"srcs_ros2-{_version()}-py3-none-any.whl"
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        modules = {n: archive.read(n) for n in names if n.startswith("supervisord/")}
        info = f"srcs_ros2-{_version()}.dist-info"
        metadata = archive.read(f"{info}/METADATA").decode()
    site = unpacked / SITE.lstrip("/")
    packaged = {
        str(p.relative_to(site)): p.read_bytes()
        for p in (site / "supervisord").rglob("*")
        if p.is_file()
    }
    assert modules == packaged
    assert "Requires-Dist" not in metadata
    assert "Requires-Python: >=3.10" in metadata
    data = f"srcs_ros2-{_version()}.data/data/share"
    assert f"{data}/ament_index/resource_index/packages/srcs_ros2" in names
    assert f"{data}/srcs_ros2/package.xml" in names


def test_carries_no_path_of_the_build_machine(built: tuple[Path, Path], unpacked: Path) -> None:
    """No file of the package or the wheel names the repository, the build's scratch
    directory, the build's Python environment or a home directory."""
    deb, wheel = built
    machine = {str(ROOT), str(deb.parent.parent), sys.prefix, str(Path.home())}
    contents = [p.read_bytes() for p in unpacked.rglob("*") if p.is_file()]
    with zipfile.ZipFile(wheel) as archive:
        contents += [archive.read(name) for name in archive.namelist()]
    for data in contents:
        for path in machine:
            assert path.encode() not in data, path


def test_the_build_is_deterministic(built: tuple[Path, Path], tmp_path: Path) -> None:
    """A second build of the same tree, by someone else (another DEBEMAIL and DEBFULLNAME),
    gives the same bytes, package and wheel."""
    someone_else = {**os.environ, "DEBEMAIL": "someone.else@build.invalid", "DEBFULLNAME": "Else"}
    again = build_packages(tmp_path, someone_else)
    for first, second in zip(built, again, strict=True):
        assert first.name == second.name
        assert (
            hashlib.sha256(first.read_bytes()).digest()
            == hashlib.sha256(second.read_bytes()).digest()
        ), first.name


def test_the_launcher_runs_with_the_distributions_python(unpacked: Path) -> None:
    """``/usr/bin/srcs-ros2`` starts with ``#!/usr/bin/python3`` and, run from the unpacked
    tree by this machine's own python3, prints its help; asked to run without rclpy it says
    so and exits 2. It leaves no byte-code behind."""
    if not SYSTEM_PYTHON.exists():
        pytest.fail(f"{SYSTEM_PYTHON} is missing: the launcher's interpreter")
    launcher = unpacked / "usr/bin/srcs-ros2"
    assert launcher.read_text().startswith("#!/usr/bin/python3\n")
    env = environment(PYTHONPATH=str(unpacked / SITE.lstrip("/")))
    result = subprocess.run(
        [launcher, "--help"], capture_output=True, text=True, env=env, timeout=60, check=False
    )
    assert result.returncode == 0, result.stderr
    assert "srcs-ros2 --ros-args -p socket:=/run/srcsd/api.sock" in result.stdout
    result = subprocess.run(
        [launcher, "--ros-args"], capture_output=True, text=True, env=env, timeout=60, check=False
    )
    assert result.returncode == 2, result.stdout + result.stderr
    assert "cannot load rclpy" in result.stdout
    assert not list(unpacked.rglob("__pycache__"))


def _probe(python: Path | str, site: Path, *modules: str) -> dict[str, str]:
    result = subprocess.run(
        [python, "-I", "-B", "-c", PROBE, str(site), *modules],
        capture_output=True,
        text=True,
        env=environment(),
        timeout=120,
        check=False,
    )
    if result.returncode != 0 and "rclpy" in modules[0] and "Error" in result.stderr:
        ros_unavailable(result.stderr.strip().splitlines()[-1])
    assert result.returncode == 0, result.stderr
    files: dict[str, str] = json.loads(result.stdout)
    return files


def ros_unavailable(why: str) -> None:
    """rclpy does not load here: a failure under ``./dev test``, which installs it; else a
    skip that says why (docs/ros2.md "Testing")."""
    if os.environ.get("SRCS_ROS2_TESTS") == "required":
        pytest.fail(f"rclpy cannot be loaded: {why}")
    pytest.skip(f"rclpy cannot be loaded ({why}); ./dev test installs requirements/ros2.txt")


def test_the_packaged_modules_load_nothing_of_the_daemon(unpacked: Path) -> None:
    """Debian's python3, isolated, with the package's directory first: the client library and
    the bridge's pure modules load from the package alone, the standard library beside them,
    and none of the daemon's dependencies."""
    site = unpacked / SITE.lstrip("/")
    files = _probe(SYSTEM_PYTHON, site, "supervisord.client", *sorted(BRIDGE_MODULES))
    ours = {name for name in files if name.split(".")[0] == "supervisord"}
    assert ours == CLIENT_MODULES | BRIDGE_MODULES
    for name in ours:
        assert Path(files[name]).is_relative_to(site), (name, files[name])
    others = {name.split(".")[0] for name in files} - {"supervisord"}
    assert others <= sys.stdlib_module_names, sorted(others - sys.stdlib_module_names)
    assert not others & set(DAEMON_DEPENDENCIES)


def test_the_packaged_node_imports_with_the_jazzy_wheels(unpacked: Path) -> None:
    """The node module, from the package's directory, imports with ROS 2 Jazzy's rclpy and
    messages (the wheels ``./dev test`` installs): every module of this package it loads is
    the package's own, and none of the daemon's dependencies comes with it."""
    site = unpacked / SITE.lstrip("/")
    files = _probe(sys.executable, site, "rclpy", "supervisord.ros2.node")
    ours = {name for name in files if name.split(".")[0] == "supervisord"}
    assert ours == MODULES - {"supervisord.cli", "supervisord.cli.ros2"}
    for name in ours:
        assert Path(files[name]).is_relative_to(site), (name, files[name])
    assert not {name.split(".")[0] for name in files} & set(DAEMON_DEPENDENCIES)

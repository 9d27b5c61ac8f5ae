"""The fleet collector's package (packaging/build_collector_deb.py, docs/fleet.md "The
collector package", SR-13.10): ``srcs-collector``, architecture all; the reading tools with
one bundled dependency, pure Python (``fleet replay``, ``--plot`` and ``--mcap`` run from it),
the receiver's, Prometheus's and Alertmanager's configuration checked by their own
tools; nothing of a robot (no udev, no daemon, its users, units or rule); lintian's
approval; installed with dpkg into a root over this machine's, it runs and makes its first
targets. The fleet tier (tests/fleet/) runs a collector on this package unchanged."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from supervisord.config import toml
from tests.cli.test_fleet import STOP_ROBOT, STOPPING
from tests.journald import collect, robot_export

ROOT = Path(__file__).resolve().parents[2]
PREFIX = "opt/srcs-collector"
PROMTOOL = "/usr/bin/promtool"
AMTOOL = "/usr/bin/amtool"


def _version() -> str:
    with (ROOT / "pyproject.toml").open("rb") as handle:
        return str(toml.load(handle)["project"]["version"])


def _clean_env() -> dict[str, str]:
    """Without the developer's PYTHON* settings: the packaged tools find all in their tree."""
    return {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}


@pytest.fixture(scope="session")
def deb(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The package built from this tree once per session, as ``./dev deb --collector``."""
    if shutil.which("dpkg-deb") is None:
        pytest.fail("dpkg-deb is missing: the package cannot be built or checked")
    out = tmp_path_factory.mktemp("collector-deb")
    result = subprocess.run(
        [sys.executable, "packaging/build_collector_deb.py", "--out", str(out / "dist"),
         "--work", str(out / "work")],
        cwd=ROOT,
        env=_clean_env(),
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    return Path(result.stdout.strip())


@pytest.fixture(scope="session")
def unpacked(deb: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("collector-unpacked")
    subprocess.run(["dpkg-deb", "-x", str(deb), str(root)], check=True)
    subprocess.run(["dpkg-deb", "-e", str(deb), str(root / "DEBIAN")], check=True)
    return root


def field(deb: Path, name: str) -> str:
    return subprocess.run(
        ["dpkg-deb", "-f", str(deb), name], capture_output=True, text=True, check=True
    ).stdout.strip()


def test_name_version_architecture_and_no_robot_in_its_depends(deb: Path) -> None:
    """``srcs-collector_<version>_all.deb``; it depends on the receiver and openssl, never on
    udev or the robot's package (a collector is no robot), and conflicts with the robot's
    package, which ships its own srcsctl."""
    assert deb.name == f"srcs-collector_{_version()}_all.deb"
    assert field(deb, "Architecture") == "all"
    depends = [d.split()[0] for d in field(deb, "Depends").replace("|", ",").split(",")]
    assert "systemd-journal-remote" in depends
    assert "openssl" in depends
    assert not {"udev", "srcs-supervisord", "systemd"} & set(depends)
    assert field(deb, "Conflicts") == "srcs-supervisord"


def test_nothing_of_a_robot_in_it(unpacked: Path) -> None:
    """No sysusers (the daemon's users), no tmpfiles, no srcsd@ or srcs-exporter@ unit, no udev
    rule, no bundled third-party distribution but mcap (``fleet replay --mcap``, below), pure
    Python and without the compiled compression libraries it names; no compiled file at all
    (architecture all)."""
    files = {str(p.relative_to(unpacked)) for p in unpacked.rglob("*")}
    assert not [f for f in files if f.startswith(("usr/lib/sysusers.d", "usr/lib/tmpfiles.d"))]
    assert not [f for f in files if "udev" in f or re.search(r"srcsd@|srcs-exporter@", f)]
    site = unpacked / PREFIX / "lib/python3/site-packages"
    names = sorted(p.name for p in site.iterdir() if not p.name.startswith("mcap-"))
    assert names == ["mcap", f"srcs_supervisord-{_version()}.dist-info", "supervisord"]
    assert [p.name for p in site.glob("mcap-*.dist-info")]
    assert not [str(p) for p in unpacked.rglob("*.so*")]


def test_the_tools_run_from_the_unpacked_tree_on_the_system_python(
    unpacked: Path, tmp_path: Path
) -> None:
    """srcsctl fleet, srcs-fleet-targets and srcs-fleet-pki start from the package's tree on
    /usr/bin/python3 alone: no pyserial, python-can or prometheus-client anywhere on the path."""
    bin_dir = unpacked / PREFIX / "bin"
    for argv in (["srcsctl", "fleet", "--help"], ["srcs-fleet-targets", "--help"],
                 ["srcs-fleet-pki", "--help"]):  # fmt: skip
        result = subprocess.run(
            [str(bin_dir / argv[0]), *argv[1:]],
            capture_output=True, text=True, env=_clean_env(), timeout=60, check=False,
        )  # fmt: skip
        assert result.returncode == 0, result.stderr
    robots = tmp_path / "robots"
    robots.write_text("robot-a 192.0.2.21\n")
    out = tmp_path / "targets.yml"
    result = subprocess.run(
        [str(bin_dir / "srcs-fleet-targets"), "--robots", str(robots), "--out", str(out)],
        capture_output=True, text=True, env=_clean_env(), timeout=60, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert '"192.0.2.21:9817"' in out.read_text()


@pytest.fixture(scope="module")
def stopped_at_collector(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """robot-d of tests/cli/test_fleet.py (the real srcsd and srcs-sim, two remote e-stops in
    RUN, its own replays), its journal written by the real systemd-journal-remote into a
    collector's directory: the robot's folder and that directory."""
    base = tmp_path_factory.mktemp("collector-stops")
    folder = base / "robot-d"
    folder.mkdir()
    export = robot_export("robot-d", STOP_ROBOT, {"DIR": str(folder), "PYTHON": sys.executable})
    directory = base / "remote"
    directory.mkdir()
    collect(export, directory / f"remote-{STOPPING}.journal")
    return folder, directory


def test_the_package_replays_a_stop_draws_it_and_writes_its_mcap_file(
    unpacked: Path, stopped_at_collector: tuple[Path, Path], tmp_path: Path
) -> None:
    """SR-13.12 on the package's own tree and /usr/bin/python3 alone: ``srcsctl fleet replay
    ROBOT SEQ --plot OUT`` says what the robot's own replay says (the files named as the
    collector's copy) and draws the same picture: the replay and the picture need no module
    outside the standard library. SR-7.15: ``--mcap`` writes the stop's MCAP file at the
    collector too, from the package's bundled mcap (pure Python, the file uncompressed;
    docs/fleet.md "The collector package"), whole: mcap's reader reads every message."""
    from mcap.reader import make_reader  # noqa: PLC0415 - the reader is the test's, not the package's

    folder, directory = stopped_at_collector
    made = json.loads((folder / "stops.json").read_text())
    seq = made["seqs"][0]
    srcsctl = str(unpacked / PREFIX / "bin/srcsctl")
    robot = f"robot-d@{STOPPING}"
    plot = tmp_path / "stop.svg"
    there = subprocess.run(
        [srcsctl, "fleet", "replay", robot, str(seq), "-D", str(directory), "--plot", str(plot)],
        capture_output=True, text=True, env=_clean_env(), timeout=120, check=False,
    )  # fmt: skip
    own_status, own = (folder / f"robot-{seq}.txt").read_text().split("\n", 1)
    assert own_status == "0", own
    named = f"{robot}'s window of #{seq} at the collector"
    expected = own.replace(f"{made['record']}.flight/{seq}.jsonl", named).replace(
        str(folder / f"robot-{seq}.svg"), str(plot)
    )
    assert there.returncode == 0, there.stdout + there.stderr
    assert there.stdout == expected
    assert plot.read_bytes() == (folder / f"robot-{seq}.svg").read_bytes()
    film = tmp_path / "stop.mcap"
    written = subprocess.run(
        [srcsctl, "fleet", "replay", robot, str(seq), "-D", str(directory), "--mcap", str(film)],
        capture_output=True, text=True, env=_clean_env(), timeout=120, check=False,
    )  # fmt: skip
    assert written.returncode == 0, written.stdout + written.stderr
    assert f"mcap: wrote {film}" in written.stdout, written.stdout
    with film.open("rb") as file:
        reader = make_reader(file)
        summary = reader.get_summary()
        assert summary is not None
        topics = {channel.topic for channel in summary.channels.values()}
        messages = sum(1 for _ in reader.iter_messages())
    assert "/core/state" in topics, topics
    assert messages > 0


def test_the_build_refuses_a_bundled_wheel_that_is_not_pure_python(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Architecture ``all`` holds only while every bundled wheel is pure Python: a locked
    distribution with compiled modules (msgpack, from the same wheel store) in BUNDLED is
    refused by name, and nothing of it reaches the package's site-packages."""
    spec = importlib.util.spec_from_file_location(
        "build_collector_deb", ROOT / "packaging/build_collector_deb.py"
    )
    assert spec is not None
    assert spec.loader is not None
    build = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build)
    monkeypatch.setattr(build, "BUNDLED", frozenset({"msgpack"}))
    site = tmp_path / "site"
    site.mkdir()
    with pytest.raises(build.BuildError, match=r"msgpack-[^ ]*\.dist-info is not pure Python"):
        build.install_bundled(tmp_path / "work", site)
    assert list(site.iterdir()) == []


def test_lintian_finds_no_error_and_no_warning(deb: Path) -> None:
    """SR-0.2, as the robot's package: no error, no warning but those overridden, and no
    override unused."""
    if shutil.which("lintian") is None:
        pytest.fail("lintian is missing (./dev test installs it)")
    result = subprocess.run(
        ["lintian", "--info", "--display-info", "--fail-on", "error,warning", str(deb)],
        capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    tags = [line for line in result.stdout.splitlines() if re.match(r"[EWIPX]: ", line)]
    assert [t for t in tags if t.startswith(("E:", "W:")) or "-override" in t] == []
    assert result.returncode == 0, result.stdout + result.stderr


def test_conffiles_are_the_files_in_etc(unpacked: Path) -> None:
    """What the administrator edits (the robots' list, Prometheus's and Alertmanager's
    configuration) is a conffile: an upgrade keeps the edits."""
    in_etc = sorted(f"/{p.relative_to(unpacked)}" for p in (unpacked / "etc").rglob("*")
                    if p.is_file())  # fmt: skip
    assert sorted((unpacked / "DEBIAN/conffiles").read_text().split()) == in_etc


@pytest.mark.skipif(not Path(PROMTOOL).exists(), reason="needs Debian's prometheus package")
def test_prometheus_accepts_the_shipped_configuration(unpacked: Path, tmp_path: Path) -> None:
    """promtool checks the shipped prometheus.yml with the shipped rules and a targets file
    srcs-fleet-targets wrote (their absolute paths pointed at the unpacked tree)."""
    config = (unpacked / "etc/srcs-collector/prometheus.yml").read_text()
    targets = tmp_path / "targets"
    targets.mkdir()
    (targets / "robots.yml").write_text('- targets: ["192.0.2.21:9817"]\n  labels: {robot: "a"}\n')
    config = config.replace("/usr/share/srcs-collector/", f"{unpacked}/usr/share/srcs-collector/")
    config = config.replace("/var/lib/srcs-collector/targets/", f"{targets}/")
    (tmp_path / "prometheus.yml").write_text(config)
    result = subprocess.run(
        [PROMTOOL, "check", "config", str(tmp_path / "prometheus.yml")],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.skipif(not Path(AMTOOL).exists(), reason="needs Debian's prometheus-alertmanager")
def test_alertmanager_routes_by_robot_and_inhibits(unpacked: Path) -> None:
    """amtool accepts the shipped alertmanager.yml, and its routes take every robot's alert
    to the team's receiver grouped by the robot."""
    config = str(unpacked / "etc/srcs-collector/alertmanager.yml")
    checked = subprocess.run(
        [AMTOOL, "check-config", config], capture_output=True, text=True, timeout=60, check=False
    )
    assert checked.returncode == 0, checked.stdout + checked.stderr
    routed = subprocess.run(
        [AMTOOL, "config", "routes", "test", f"--config.file={config}", "--verify.receivers",
         "fleet-team", "alertname=SrcsStopped", "robot=robot-a"],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert routed.returncode == 0, routed.stdout + routed.stderr


def test_units_pass_systemd_analyze_verify(unpacked: Path) -> None:
    """The retention's and the targets' units are valid for systemd (their commands pointed
    at the unpacked tree: verify checks that each exists)."""
    if shutil.which("systemd-analyze") is None:
        pytest.fail("systemd-analyze is missing")
    units = unpacked / "usr/lib/systemd/system"
    service = units / "srcs-collector-targets.service"
    service.write_text(service.read_text().replace("/usr/sbin/", f"{unpacked}/{PREFIX}/bin/"))
    result = subprocess.run(
        ["systemd-analyze", "verify", *(str(units / name) for name in (
            "srcs-collector-retention.service", "srcs-collector-retention.timer",
            "srcs-collector-targets.path", "srcs-collector-targets.service"))],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr


def test_dpkg_installs_it_on_a_machine_that_is_no_robot(deb: Path, tmp_path: Path) -> None:
    """``dpkg -i`` into an overlay over this machine's root (which has no srcs-supervisord):
    its dependencies hold, postinst byte-compiles and writes the first (empty) targets file,
    srcsctl fleet answers from the installed tree, and no user of the daemon was made."""
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        pytest.skip("needs root and unshare: dpkg -i into an overlay root")
    script = r"""
set -eu
mkdir -p "$W/upper" "$W/ovl" "$W/root"
mount -t overlay overlay -o "lowerdir=/,upperdir=$W/upper,workdir=$W/ovl" "$W/root"
mount -t proc proc "$W/root/proc"
mount -t tmpfs tmp "$W/root/tmp"
mount -t tmpfs run "$W/root/run"
mkdir -p "$W/root/srv/deb" && mount --bind "$(dirname "$DEB")" "$W/root/srv/deb"
chroot "$W/root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin \
    dpkg -i "/srv/deb/$(basename "$DEB")"
chroot "$W/root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin \
    srcsctl fleet --directory /tmp --summary || echo "fleet exit $?"
cat "$W/root/var/lib/srcs-collector/targets/robots.yml"
chroot "$W/root" getent passwd srcsd || echo "no srcsd user"
"""
    result = subprocess.run(
        ["unshare", "--mount", "--propagation", "private", "sh", "-c", script],
        env={"PATH": "/usr/sbin:/usr/bin:/sbin:/bin", "W": str(tmp_path), "DEB": str(deb)},
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Setting up srcs-collector" in result.stdout
    assert "[]" in result.stdout  # the first targets: none yet
    assert "no srcsd user" in result.stdout
    assert list((tmp_path / "upper/opt/srcs-collector").rglob("*.pyc"))  # postinst compiled

"""The collector's tools (SR-13.10, docs/fleet.md "The collector package"): srcs-fleet-targets
writes Prometheus's targets from the robots' list and refuses a bad list without touching the
old file; srcs-fleet-pki makes a CA, the collector's and the robots' certificates with the
real openssl, and renews the CA so that what it signed stays valid."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from supervisord.cli import fleet_pki, fleet_targets


def test_targets_from_the_list_name_each_robot(tmp_path: Path) -> None:
    robots = tmp_path / "robots"
    robots.write_text(
        "# the fleet\nrobot-a 192.0.2.21\nrobot-b\nrobot-c [2001:db8::1]:9000 # ipv6\n"
    )
    out = tmp_path / "t/robots.yml"
    assert fleet_targets.main(["--robots", str(robots), "--out", str(out)]) == 0
    assert out.read_text().splitlines()[1:] == [
        '- targets: ["192.0.2.21:9817"]',
        '  labels: {robot: "robot-a"}',
        '- targets: ["robot-b:9817"]',
        '  labels: {robot: "robot-b"}',
        '- targets: ["[2001:db8::1]:9000"]',
        '  labels: {robot: "robot-c"}',
    ]


@pytest.mark.parametrize(
    ("line", "says"),
    [
        ("robot-a 192.0.2.1\nrobot-a 192.0.2.2", "line 2: the name robot-a is on line 1 too"),
        ("robot-a 192.0.2.1\nrobot-b 192.0.2.1", "line 2: the address 192.0.2.1:9817"),
        ("robot-a 192.0.2.1:99999", "line 1: '192.0.2.1:99999': the port"),
        ("-x", "line 1: '-x' is not a robot's host name"),
        ("robot-a 2001:db8::1", "line 1: '2001:db8::1': an IPv6 address goes in brackets"),
        ("robot-a b c", "line 1: one robot a line"),
        ("robot-a \x1b[2J", "is not a host name or address"),
    ],
)
def test_a_bad_list_is_refused_and_the_old_targets_stay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], line: str, says: str
) -> None:
    robots, out = tmp_path / "robots", tmp_path / "robots.yml"
    out.write_text("old\n")
    robots.write_text(line + "\n")
    assert fleet_targets.main(["--robots", str(robots), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert says in err
    assert "\x1b" not in err
    assert out.read_text() == "old\n"


def _openssl(*args: str) -> str:
    return subprocess.run(["openssl", *args], capture_output=True, text=True, check=True).stdout


def test_certificates_made_checked_and_the_ca_renewed(tmp_path: Path) -> None:
    if shutil.which("openssl") is None:
        pytest.fail("openssl is missing")
    pki = tmp_path / "pki"
    assert fleet_pki.main(["--dir", str(pki), "ca"]) == 0
    assert fleet_pki.main(["--dir", str(pki), "server", "journal.fleet.example", "192.0.2.10"]) == 0
    assert fleet_pki.main(["--dir", str(pki), "robot", "robot-a", "robot-b"]) == 0
    text = _openssl("x509", "-in", str(pki / "collector.pem"), "-noout", "-text")
    assert "DNS:journal.fleet.example, IP Address:192.0.2.10" in text
    assert "TLS Web Server Authentication" in text
    robot = _openssl("x509", "-in", str(pki / "robot-a.pem"), "-noout", "-subject", "-text")
    # OpenSSL 3.0 (Debian 12) prints "CN = robot-a", 3.5 (Debian 13 and later) "CN=robot-a".
    assert "CN=robot-a" in robot.replace(" = ", "=")
    assert "TLS Web Client Authentication" in robot
    assert (pki / "robot-a.key").stat().st_mode & 0o077 == 0
    old_ca = (pki / "ca.pem").read_bytes()
    assert fleet_pki.main(["--dir", str(pki), "ca"]) == 0  # renewed with the same key
    assert (pki / "ca.pem").read_bytes() != old_ca
    _openssl("verify", "-CAfile", str(pki / "ca.pem"), str(pki / "robot-a.pem"),
             str(pki / "collector.pem"))  # fmt: skip


def test_a_robot_certificate_without_a_ca_or_with_a_bad_name_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pki = tmp_path / "pki"
    assert fleet_pki.main(["--dir", str(pki), "robot", "robot-a"]) == 1
    assert "no CA in" in capsys.readouterr().err
    assert fleet_pki.main(["--dir", str(pki), "ca"]) == 0
    assert fleet_pki.main(["--dir", str(pki), "robot", "bad name"]) == 1
    assert fleet_pki.main(["--dir", str(pki), "robot", "collector"]) == 1
    assert not list(pki.glob("bad*"))
    assert not (pki / "collector.pem").exists()

"""The fleet tier's certificates, made with openssl: a test CA, the collector's server
certificate for its loopback address (an IP SAN: systemd-journal-upload checks the name it
connects to), and a client certificate per robot whose CN is the robot's name (what
systemd-journal-remote checks against the CA, and names the robot's output file by).

Every certificate starts a day in the past (openssl run under ``faketime``): a robot whose
clock is minutes behind (SR-13.3) must still find the collector's certificate valid."""

from __future__ import annotations

import subprocess
from pathlib import Path

COLLECTOR_ADDRESS = "127.0.0.10"
DAYS = "3"


def _openssl(*args: str) -> None:
    subprocess.run(["faketime", "-f", "-1d", "openssl", *args], check=True, capture_output=True)


def _signed(pki: Path, name: str, subject: str, extensions: str) -> None:
    key, csr, ext = pki / f"{name}.key", pki / f"{name}.csr", pki / f"{name}.ext"
    _openssl("genrsa", "-out", str(key), "2048")
    _openssl("req", "-new", "-key", str(key), "-subj", subject, "-out", str(csr))
    ext.write_text(extensions)
    _openssl(
        "x509", "-req", "-in", str(csr), "-CA", str(pki / "ca.pem"), "-CAkey",
        str(pki / "ca.key"), "-CAcreateserial", "-days", DAYS, "-sha256", "-extfile",
        str(ext), "-out", str(pki / f"{name}.pem"),
    )  # fmt: skip
    csr.unlink()
    ext.unlink()


def make(pki: Path, robots: list[str]) -> None:
    """The CA, ``collector.key``/``collector.pem`` and ``ROBOT.key``/``ROBOT.pem`` in ``pki``."""
    pki.mkdir(parents=True, exist_ok=True)
    _openssl("genrsa", "-out", str(pki / "ca.key"), "2048")
    _openssl(
        "req", "-x509", "-new", "-key", str(pki / "ca.key"), "-days", DAYS, "-sha256",
        "-subj", "/CN=srcs fleet tier CA", "-out", str(pki / "ca.pem"),
    )  # fmt: skip
    _signed(
        pki,
        "collector",
        "/CN=collector",
        f"subjectAltName=IP:{COLLECTOR_ADDRESS}\nextendedKeyUsage=serverAuth\n",
    )
    for robot in robots:
        _signed(pki, robot, f"/CN={robot}", "extendedKeyUsage=clientAuth\n")
    for key in pki.glob("*.key"):
        key.chmod(0o600)

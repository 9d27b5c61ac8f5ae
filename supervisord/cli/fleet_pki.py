"""``srcs-fleet-pki``: the fleet's certificates, made and renewed with openssl (SR-13.10,
docs/fleet.md "Certificates").

    srcs-fleet-pki ca                               # the fleet's CA (renews it when it exists)
    srcs-fleet-pki server journal.fleet.example 192.0.2.10   # the collector's, for its names
    srcs-fleet-pki robot robot-a robot-b            # one per robot, its name as the CN
    srcs-fleet-pki status                           # each certificate and its days left

Everything goes into one directory (``/etc/srcs-collector/pki``): ``ca.key``/``ca.pem``,
``collector.key``/``collector.pem``, ``NAME.key``/``NAME.pem``. Keys are 0600 (the
collector's 0640 to the receiver's group, ``systemd-journal-remote``, which reads it).

Renewing is making again: ``server`` and ``robot`` make a new key and certificate, signed by
the same CA; ``ca`` on an existing CA signs a new CA certificate with the same key and
subject, so every certificate it signed stays valid under the new one. A robot's CN is its
host name, which a receiver that checks client certificates (built with GnuTLS, ``--trust``)
names its file by; the collector's certificate carries every name and address the robots
connect to (systemd-journal-upload checks it).

openssl does the cryptography; this is only the fleet's recipe, so that no team writes its
own. Every failure is a refusal in words (exit 1), never a half-written pair: a key and its
certificate are written beside their final names and renamed together at the end.
"""

from __future__ import annotations

import argparse
import datetime as dt
import grp
import ipaddress
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Final

from supervisord import __version__
from supervisord.cli.fleet_journal import robot_name
from supervisord.cli.terminal_text import printable

PKI: Final = Path("/etc/srcs-collector/pki")
RECEIVER_GROUP: Final = "systemd-journal-remote"
"""The user systemd-journal-remote.service runs as; its group may read the collector's key."""
CA_DAYS: Final = 3650
LEAF_DAYS: Final = 397
"""A year and a month: renewed yearly, with a month's slack."""
EXIT_FAILED: Final = 1
EXIT_BAD_INPUT: Final = 2


class PkiError(Exception):
    """A step failed; the message says which and why."""


def _openssl(*args: str) -> str:
    openssl = shutil.which("openssl")
    if openssl is None:
        raise PkiError("openssl not found: apt-get install openssl")
    result = subprocess.run(  # noqa: S603 - openssl from the path, our own arguments
        [openssl, *args], capture_output=True, text=True, check=False, timeout=120
    )
    if result.returncode != 0:
        raise PkiError(f"openssl {args[0]} failed: {result.stderr.strip()[-600:]}")
    return result.stdout


def _install(pki: Path, scratch: Path, name: str, key_group: str | None = None) -> None:
    """``scratch/NAME.key`` and ``.pem`` as ``pki/NAME.key`` and ``.pem``: the key 0600 (0640
    to ``key_group`` when it exists and we may give it), the certificate 0644."""
    key, cert = scratch / f"{name}.key", scratch / f"{name}.pem"
    key.chmod(0o600)
    if key_group is not None and os.geteuid() == 0:
        try:
            os.chown(key, 0, grp.getgrnam(key_group).gr_gid)
            key.chmod(0o640)
        except KeyError:
            pass  # no receiver on this machine: the key stays root's
    cert.chmod(0o644)
    os.replace(key, pki / f"{name}.key")
    os.replace(cert, pki / f"{name}.pem")


def make_ca(pki: Path, days: int) -> str:
    """A new CA, or the existing CA's key re-signed for ``days`` more (its subject kept)."""
    with tempfile.TemporaryDirectory(dir=pki, prefix=".ca.") as temporary:
        scratch = Path(temporary)
        key = pki / "ca.key"
        if key.exists():
            shutil.copy2(key, scratch / "ca.key")
            subject = _openssl("x509", "-in", str(pki / "ca.pem"), "-noout", "-subject",
                               "-nameopt", "compat").strip().removeprefix("subject=")  # fmt: skip
            said = "renewed (same key: every certificate it signed stays valid)"
        else:
            _openssl("genrsa", "-out", str(scratch / "ca.key"), "3072")
            subject, said = "/CN=srcs fleet CA", "made"
        _openssl(
            "req", "-x509", "-new", "-key", str(scratch / "ca.key"), "-days", str(days),
            "-sha256", "-subj", subject, "-addext", "basicConstraints=critical,CA:TRUE",
            "-addext", "keyUsage=critical,keyCertSign,cRLSign", "-out", str(scratch / "ca.pem"),
        )  # fmt: skip
        _install(pki, scratch, "ca")
    return f"ca.pem: {said}, {days} days"


def _signed(pki: Path, name: str, cn: str, extensions: str, days: int) -> None:
    if not (pki / "ca.key").exists():
        raise PkiError(f"no CA in {pki}: run 'srcs-fleet-pki ca' first")
    with tempfile.TemporaryDirectory(dir=pki, prefix=f".{name}.") as temporary:
        scratch = Path(temporary)
        key, csr, ext = scratch / f"{name}.key", scratch / "req.csr", scratch / "ext.cnf"
        _openssl("genrsa", "-out", str(key), "2048")
        _openssl("req", "-new", "-key", str(key), "-subj", f"/CN={cn}", "-out", str(csr))
        ext.write_text(extensions)
        _openssl(
            "x509", "-req", "-in", str(csr), "-CA", str(pki / "ca.pem"), "-CAkey",
            str(pki / "ca.key"), "-CAcreateserial", "-CAserial", str(scratch / "ca.srl"),
            "-days", str(days), "-sha256", "-extfile", str(ext),
            "-out", str(scratch / f"{name}.pem"),
        )  # fmt: skip
        _install(pki, scratch, name, RECEIVER_GROUP if name == "collector" else None)


def subject_alt_names(names: Sequence[str]) -> str:
    """``IP:`` for each address, ``DNS:`` for each host name. Raises ``ValueError``."""
    entries = []
    for name in names:
        try:
            entries.append(f"IP:{ipaddress.ip_address(name)}")
        except ValueError:
            entries.append(f"DNS:{robot_name(name)}")
    return ",".join(entries)


def make_server(pki: Path, names: Sequence[str], days: int) -> str:
    _signed(
        pki, "collector", names[0],
        f"subjectAltName={subject_alt_names(names)}\nextendedKeyUsage=serverAuth\n", days,
    )  # fmt: skip
    return f"collector.pem: {', '.join(names)}, {days} days"


def make_robot(pki: Path, name: str, days: int) -> str:
    robot_name(name)
    if name in ("ca", "collector"):
        raise PkiError(f"{name!r} is the name of the fleet's own certificate, not a robot's")
    _signed(pki, name, name, "extendedKeyUsage=clientAuth\n", days)
    return f"{name}.pem: {days} days"


def status(pki: Path, now: dt.datetime) -> list[str]:
    """Each certificate in ``pki``: its subject and the days it has left."""
    lines = []
    for cert in sorted(pki.glob("*.pem")):
        end = _openssl("x509", "-in", str(cert), "-noout", "-enddate").strip()
        until = dt.datetime.strptime(end.removeprefix("notAfter="), "%b %d %H:%M:%S %Y %Z")
        left = (until.replace(tzinfo=dt.timezone.utc) - now).days
        lines.append(f"{cert.name}: {left} days left (until {until:%Y-%m-%d})")
    return lines


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="srcs-fleet-pki",
        description="Make and renew the fleet's certificates with openssl: the CA, the "
        "collector's server certificate, one client certificate per robot. Making again "
        "is renewing.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument(
        "--dir", metavar="DIR", default=str(PKI), help=f"where they are (default: {PKI})"
    )
    parser.add_argument("--days", type=int, metavar="N", help="validity in days")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    commands.add_parser("ca", help=f"make the CA, or renew it with its key ({CA_DAYS} days)")
    server = commands.add_parser(
        "server", help=f"the collector's certificate for its names and addresses ({LEAF_DAYS} d)"
    )
    server.add_argument("names", nargs="+", metavar="NAME", help="host names and addresses")
    robot = commands.add_parser("robot", help=f"a robot's certificate, CN=NAME ({LEAF_DAYS} d)")
    robot.add_argument("robots", nargs="+", metavar="NAME", help="the robots' host names")
    commands.add_parser("status", help="each certificate and the days it has left")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    pki = Path(args.dir)
    if args.days is not None and not 1 <= args.days <= 36500:
        print("srcs-fleet-pki: --days is 1 to 36500", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        pki.mkdir(mode=0o755, parents=True, exist_ok=True)
        if args.command == "ca":
            said = [make_ca(pki, args.days or CA_DAYS)]
        elif args.command == "server":
            said = [make_server(pki, args.names, args.days or LEAF_DAYS)]
        elif args.command == "robot":
            said = [make_robot(pki, name, args.days or LEAF_DAYS) for name in args.robots]
        else:
            said = status(pki, dt.datetime.now(dt.timezone.utc))
    except (OSError, ValueError, PkiError, subprocess.TimeoutExpired) as error:
        print(f"srcs-fleet-pki: {printable(str(error))}", file=sys.stderr)
        return EXIT_FAILED
    for line in said:
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The Debian roots of the platform jobs: bootstrapped once a week, cached, entered safely.

A *base* root is ``debootstrap --variant=minbase --include=python3`` of one suite and
architecture from the Debian registry this machine's apt uses, with its package lists
fetched. It is cached as a directory named by suite, architecture, ISO week and a hash of
how it is made (``bookworm-amd64-2026w48-1a2b3c4d``), so a warm run never bootstraps, and a
new week (or a change of recipe) bootstraps afresh, pruning the old one.

A *layer* is what a job installs on a base (the test suite's dependencies, systemd): the
upper directory of an overlay, cached beside the bases under a name that hashes its recipe.
A job's own run writes into a scratch upper directory over the base and its layers, which
stay read-only, so every run starts from the same tree.

Every command in a root runs through ``tests/platforms/enter``: a private mount and PID
namespace (and a network namespace where asked), a fresh ``/proc``, a private ``/dev``, and
``policy-rc.d``. The one exception is ``debootstrap`` itself, which chroots into the root it
makes: it runs inside a private mount and PID namespace too, with ``policy-rc.d`` in the root
before the first package. Nothing is mounted on the host and nothing of the host's root is
touched (docs/platforms.md).
"""

from __future__ import annotations

import datetime
import hashlib
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
ENTER = HERE / "enter"
CACHE = (
    Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "srcs-platforms"
).resolve()
BASE_PACKAGES = ("python3",)
"""What every base root has beyond minbase: the interpreter every job needs there."""
APT_CONF = """\
// srcs-platforms: no recommends, no translations, apt's own output plain.
APT::Install-Recommends "false";
Acquire::Languages "none";
Dpkg::Use-Pty "false";
// A mirror that serves a snapshot of unstable keeps its Release file after its Valid-Until
// date; the signature is still checked.
Acquire::Check-Valid-Until "false";
"""


class RootError(Exception):
    """A root could not be made or entered; the message has the end of the output."""


def host_codename() -> str:
    for line in Path("/etc/os-release").read_text().splitlines():
        if line.startswith("VERSION_CODENAME="):
            return line.split("=", 1)[1].strip('"')
    raise RootError("no VERSION_CODENAME in /etc/os-release")


def _one_line_sources() -> list[tuple[str, str]]:
    """(URI, suite) of every ``deb`` line of sources.list and sources.list.d/*.list."""
    entries: list[tuple[str, str]] = []
    paths = [Path("/etc/apt/sources.list"), *sorted(Path("/etc/apt/sources.list.d").glob("*.list"))]
    for path in paths:
        if not path.is_file():
            continue
        for line in path.read_text().splitlines():
            words = line.split("#", 1)[0].split()
            if len(words) < 3 or words[0] != "deb":
                continue
            rest = words[1:]  # deb [options] URI SUITE COMPONENTS...
            if rest[0].startswith("["):
                while rest and not rest[0].endswith("]"):
                    rest = rest[1:]
                rest = rest[1:]
            if len(rest) >= 2:
                entries.append((rest[0], rest[1]))
    return entries


def _deb822_sources() -> list[tuple[str, str]]:
    """(URI, suite) of every enabled ``deb`` stanza of sources.list.d/*.sources."""
    entries: list[tuple[str, str]] = []
    for path in sorted(Path("/etc/apt/sources.list.d").glob("*.sources")):
        for stanza in path.read_text().split("\n\n"):
            fields: dict[str, str] = {}
            for line in stanza.splitlines():
                if line.startswith("#") or ":" not in line or line[0].isspace():
                    continue
                key, value = line.split(":", 1)
                fields[key.strip().lower()] = value.strip()
            enabled = fields.get("enabled", "yes").lower() != "no"
            if enabled and "deb" in fields.get("types", "").split():
                for uri in fields.get("uris", "").split():
                    entries.extend((uri, suite) for suite in fields.get("suites", "").split())
    return entries


def mirror() -> str:
    """The Debian registry this machine's apt installs its own release from. The roots'
    suites come from the same one: a Debian mirror serves every suite."""
    if os.environ.get("SRCS_PLATFORMS_MIRROR"):
        return os.environ["SRCS_PLATFORMS_MIRROR"]
    codename = host_codename()
    for uri, suite in [*_one_line_sources(), *_deb822_sources()]:
        if suite == codename:
            return uri.rstrip("/")
    raise RootError(
        f"no 'deb' source for {codename} in /etc/apt: set SRCS_PLATFORMS_MIRROR to a Debian mirror"
    )


def week() -> str:
    """The ISO week, the roots' lifetime: bootstrapped afresh once a week."""
    year, number, _ = datetime.datetime.now(datetime.timezone.utc).isocalendar()
    return f"{year}w{number:02d}"


def digest(*parts: str | bytes) -> str:
    sha = hashlib.sha256()
    for part in parts:
        sha.update(part.encode() if isinstance(part, str) else part)
        sha.update(b"\0")
    return sha.hexdigest()[:12]


def run(
    command: Sequence[str | Path],
    *,
    timeout: float,
    env: Mapping[str, str] | None = None,
    show: bool = False,
) -> subprocess.CompletedProcess[str]:
    """A host command; its output is captured (and echoed when ``show``), never raised on."""
    result = subprocess.run(
        [str(part) for part in command],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
        env=None if env is None else {**os.environ, **env},
    )
    if show:
        sys.stdout.write(result.stdout + result.stderr)
        sys.stdout.flush()
    return result


def enter(
    command: Sequence[str],
    *,
    layers: Sequence[Path] = (),
    work: Path | None = None,
    root: Path | None = None,
    net: bool = False,
    binds: Sequence[tuple[Path, str]] = (),
    env: Mapping[str, str] | None = None,
    timeout: float = 600,
    show: bool = False,
) -> subprocess.CompletedProcess[str]:
    """``command`` inside a root: ``root`` changed in place, or an overlay of ``layers``
    (uppermost first) with ``work``/upper on top. ``env`` is the command's environment
    beyond the clean one ``enter`` gives."""
    args: list[str | Path] = [ENTER]
    if net:
        args.append("--net")
    for source, target in binds:
        args += ["--bind", f"{source}:{target}"]
    if root is not None:
        args += ["--root", root]
    else:
        assert work is not None
        assert layers
        for layer in layers:
            args += ["--lower", layer]
        args += ["--work", work]
    passed = {f"SRCS_ENV_{key}": value for key, value in (env or {}).items()}
    return run([*args, "--", *command], timeout=timeout, env=passed, show=show)


def _fail(what: str, result: subprocess.CompletedProcess[str]) -> RootError:
    output = (result.stdout + result.stderr).splitlines()[-30:]
    return RootError(f"{what} failed ({result.returncode}):\n" + "\n".join(output))


def _prune(prefix: str, keep: str) -> None:
    """Remove the cached trees named ``prefix``... other than ``keep`` and the layers made on
    it: last week's roots, an old recipe's, and every layer made on those."""
    if not (CACHE / "roots").is_dir():
        return
    for path in (CACHE / "roots").iterdir():
        name = path.name
        if name.startswith(prefix) and name != keep and not name.startswith(keep + "+"):
            shutil.rmtree(path, ignore_errors=True)


def base(suite: str, arch: str, *, log: bool = True) -> Path:
    """The cached base root of ``suite`` for ``arch``, bootstrapped when missing."""
    recipe = digest(suite, arch, " ".join(BASE_PACKAGES), APT_CONF)[:8]
    name = f"{suite}-{arch}-{week()}-{recipe}"
    path = CACHE / "roots" / name
    _prune(f"{suite}-{arch}-", name)
    if (path / "etc/debian_version").is_file():
        if log:
            print(f"roots: {name}: cached", flush=True)
        return path
    source = mirror()
    partial = path.with_name(name + ".partial")
    # debootstrap chroots into the root and mounts /proc and /sys there itself: inside a
    # private mount and PID namespace, those mounts (and every process it leaves) end with
    # it. The device nodes it makes are its own, in the root's /dev, never the host's. Not
    # --foreign: the second stage would parse the package lists under qemu too, which doubles
    # an arm64 bootstrap.
    private = ["unshare", "--mount", "--propagation", "private", "--pid", "--fork", "--kill-child"]
    options = ["--variant=minbase", f"--arch={arch}", f"--include={','.join(BASE_PACKAGES)}"]
    for attempt in (1, 2):
        # Twice, from nothing: a download cut short (seen once as an InRelease that did not
        # come, then "Error executing gpgv") fails a whole bootstrap.
        shutil.rmtree(partial, ignore_errors=True)
        # policy-rc.d before anything is installed: no maintainer script starts a service.
        policy = partial / "usr/sbin/policy-rc.d"
        policy.parent.mkdir(parents=True)
        policy.write_text("#!/bin/sh\n# srcs-platforms: no service starts in this root\nexit 101\n")
        policy.chmod(0o755)
        bootstrap = run([*private, "debootstrap", *options, suite, partial, source], timeout=1800)
        if bootstrap.returncode == 0:
            break
        if attempt == 1:
            print(f"roots: debootstrap {suite} {arch} failed; once more", flush=True)
            time.sleep(10)
    else:
        raise _fail(f"debootstrap {suite} {arch}", bootstrap)
    (partial / "etc/apt/apt.conf.d/99srcs-platforms").write_text(APT_CONF)
    # The package lists come with the root: a job installs from them without fetching them.
    update = enter(["apt-get", "update", "-qq"], root=partial, timeout=600)
    if update.returncode != 0:
        raise _fail(f"apt-get update in {suite} {arch}", update)
    enter(["apt-get", "clean"], root=partial, timeout=120)
    partial.rename(path)
    if log:
        print(f"roots: {name}: bootstrapped from the host's Debian registry", flush=True)
    return path


def layer(
    below: Sequence[Path],
    label: str,
    script: str,
    *,
    key: Sequence[str | bytes] = (),
    binds: Sequence[tuple[Path, str]] = (),
    env: Mapping[str, str] | None = None,
    timeout: float = 1800,
) -> Path:
    """A cached layer over ``below`` (uppermost first): what ``script`` (``sh -c``) writes,
    run with the network (for apt and pip). Named by ``below``'s base, ``label`` and a hash
    of the script, ``key`` and the layers below, so a change to any of them remakes it."""
    base_name = below[-1].name
    name = f"{base_name}+{label}-{digest(script, *key, *(p.name for p in below))}"
    path = CACHE / "roots" / name
    _prune(f"{base_name}+{label}-", name)
    if (path / ".complete").is_file():
        print(f"roots: {name}: cached", flush=True)
        return path / "upper"
    work = path.with_name(name + ".partial")
    shutil.rmtree(work, ignore_errors=True)
    result = enter(
        ["sh", "-ec", script], layers=below, work=work, binds=binds, env=env, timeout=timeout
    )
    if result.returncode != 0:
        raise _fail(f"the layer {label} on {base_name}", result)
    shutil.rmtree(work / "ovl", ignore_errors=True)
    shutil.rmtree(work / "root", ignore_errors=True)
    (work / ".complete").write_text(script)
    work.rename(path)
    print(f"roots: {name}: made", flush=True)
    return path / "upper"


def host_ca() -> Path:
    """The certificate authorities this machine's own pip trusts. A root's pip is given the
    same (``PIP_CERT``), so that it reaches PyPI wherever the host's does: through a proxy
    that the host trusts but a fresh Debian root would not."""
    for variable in ("PIP_CERT", "REQUESTS_CA_BUNDLE", "SSL_CERT_FILE"):
        value = os.environ.get(variable)
        if value and Path(value).is_file():
            return Path(value)
    return Path("/etc/ssl/certs/ca-certificates.crt")


def scratch(job: str) -> Path:
    """A job's own directory for this run: emptied first, left afterwards for a look."""
    path = CACHE / "run" / job
    shutil.rmtree(path, ignore_errors=True)
    path.mkdir(parents=True)
    return path


def main(argv: list[str]) -> int:
    """``roots.py SUITE ARCH...``: make sure each base root is cached (``run`` does it first)."""
    if len(argv) < 2 or len(argv) % 2:
        print("usage: python3 -m tests.platforms.roots SUITE ARCH [SUITE ARCH]...", file=sys.stderr)
        return 2
    failed = 0
    for suite, arch in zip(argv[::2], argv[1::2], strict=True):
        try:
            base(suite, arch)
        except (RootError, subprocess.TimeoutExpired) as error:
            print(f"roots: FAILED {suite} {arch}: {error}", flush=True)
            failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

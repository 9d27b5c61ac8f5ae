"""A user lookup that never answers (``docs/faults.md``; SR-10.3): the real ``srcsd`` against
``srcs-sim``, in a mount namespace of its own where systemd's userdb service is a socket that
accepts and never replies, as when that service hangs. Debian's default ``nsswitch.conf`` asks
it for any uid that ``/etc/passwd`` does not have (a ``DynamicUser=`` service, a container's
uid): the lookup then waits for tens of seconds."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from supervisord.testkit.namespaces import in_private_mount
from supervisord.testkit.robot import OutputDef, Robot
from supervisord.vocabulary import State
from tests.faults.test_odd_input import _free_uid, open_socket_dir

# The userdb socket in the daemon's namespace: it listens (so a connect succeeds and the
# request is queued) and never accepts. It ends when the daemon, its parent, does.
HUNG_USERDB = (
    "import os, socket, time\n"
    "parent = os.getppid()\n"
    "listener = socket.socket(socket.AF_UNIX)\n"
    "listener.bind('/run/systemd/userdb/io.systemd.Multiplexer')\n"
    "listener.listen(64)\n"
    "open('/run/systemd/userdb/.ready', 'w').close()\n"
    "while os.getppid() == parent:\n"
    "    time.sleep(0.2)\n"
)
HELLO_WITHIN_S = 10.0  # the name is waited for 2 s (SR-10.3); the rest is a busy machine's margin


def _uses_userdb() -> bool:
    lines = Path("/etc/nsswitch.conf").read_text().splitlines()
    return any(line.split(":")[0] == "passwd" and "systemd" in line for line in lines)


class HungUserdbRobot(Robot):
    """The daemon sees an empty ``/run`` holding only a userdb socket that never answers."""

    def daemon_command(self) -> list[str]:
        command = super().daemon_command()
        mount = (
            'mount -t tmpfs srcs-userdb /run && mkdir -p /run/systemd/userdb && { "$0" -c '
            f"{_quoted(HUNG_USERDB)} & }} && "
            "while [ ! -e /run/systemd/userdb/.ready ]; do sleep 0.05; done"
        )
        return in_private_mount(mount, Path(sys.executable), command)


def _quoted(text: str) -> str:
    return "'" + text.replace("'", "'\\''") + "'"


@pytest.mark.skipif(
    os.geteuid() != 0
    or shutil.which("setpriv") is None
    or shutil.which("unshare") is None
    or not _uses_userdb(),
    reason="needs root, setpriv, unshare and nsswitch.conf's passwd asking systemd (Debian's)",
)
def test_a_hung_user_lookup_freezes_nothing(tmp_path: Path) -> None:
    """SR-10.3, SR-5.1: a program under a uid with no passwd entry connects and says hello while
    the userdb service hangs. The robot keeps running (the user heartbeat reaches the VSC, whose
    watchdog would otherwise trip in 500 ms), ``status`` answers meanwhile, and the program's
    hello is answered within the name's 2 s wait (the uid standing in for the name). Before, the
    lookup ran in the loop: 45 s without a user heartbeat, the drive on, ``status`` dead."""
    uid = _free_uid()
    with open_socket_dir() as folder:
        robot = HungUserdbRobot(tmp_path / "robot", outputs=(OutputDef("drive"),))
        robot.socket_path = folder / "api.sock"
        with robot:
            robot.arm()
            t0 = robot.now()
            program = (
                "import sys, time\n"
                "from supervisord.client import SupervisorClient\n"
                "t = time.monotonic()\n"
                f"with SupervisorClient.connect({str(robot.socket_path)!r}, timeout=60) as api:\n"
                "    api.hello('probe')\n"
                "    print(round(time.monotonic() - t, 3))\n"
            )
            env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
            as_user = ["setpriv", f"--reuid={uid}", "--regid=0", "--clear-groups", "--"]
            client = subprocess.Popen(
                [*as_user, sys.executable, "-c", program],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                env=env,
            )
            try:
                # While the lookup hangs, the daemon answers and the robot runs.
                asked = time.monotonic()
                assert robot.status().report.state is State.RUN
                assert time.monotonic() - asked < HELLO_WITHIN_S
                out, err = client.communicate(timeout=60)
            finally:
                client.kill()
            assert client.returncode == 0, err.decode(errors="replace")
            assert float(out) < HELLO_WITHIN_S
            robot.stays_running(0.5)
            left = [r for r in robot.records_since(t0) if r.to_state is not State.RUN]
            assert left == []

"""What the client library and the bridge load (docs/ros2.md "The client library"): a small,
named set of this package's modules and the standard library, never the safety core nor a
dependency of the daemon, so that they run on a ROS installation's own Python. Each import
runs in a fresh ``python -I`` whose ``sys.modules`` is compared before and after; the modules
must come from this tree."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

CLIENT_MODULES = frozenset(
    {
        "supervisord",
        "supervisord.api",
        "supervisord.api.connection",
        "supervisord.api.framing",
        "supervisord.api.messages",
        "supervisord.api.ops",
        "supervisord.api.pushes",
        "supervisord.record",
        "supervisord.record.stop",
        "supervisord.vocabulary",
        "supervisord.wire",
        "supervisord.api.replies",
        "supervisord.api.status",
        "supervisord.api.wire",
        "supervisord.client",
        "supervisord.compat",
        "supervisord.errors",
        "supervisord.protocol",
        "supervisord.protocol.codes",
        "supervisord.protocol.text",
        "supervisord.release",
        "supervisord.strict",
    }
)
"""Every module ``import supervisord.client`` loads: the named set of docs/ros2.md."""
BRIDGE_MODULES = frozenset(
    {
        "supervisord.api.readiness",
        "supervisord.cli",
        "supervisord.cli.ros2",
        "supervisord.ros2",
        "supervisord.ros2.command",
        "supervisord.ros2.diagnostics",
        "supervisord.ros2.gate",
        "supervisord.ros2.link",
        "supervisord.ros2.mapping",
        "supervisord.ros2.parameters",
    }
)
"""The bridge's modules that need no rclpy; ``supervisord.ros2.node`` is the one that does."""
DAEMON_DEPENDENCIES = ("serial", "can", "gpiod", "prometheus_client", "msgpack", "tomli")
"""The daemon's third-party imports (pyproject.toml's dependencies), named for the message."""

PROBE = """
import json, sys
sys.path.insert(0, sys.argv[1])
before = set(sys.modules)
for name in sys.argv[2:]:
    __import__(name)
print(json.dumps({
    name: getattr(sys.modules[name], "__file__", None) or ""
    for name in sorted(set(sys.modules) - before)
}))
"""


def loaded(*modules: str) -> dict[str, str]:
    """Every module that importing ``modules`` loads in a fresh isolated interpreter (no
    PYTHONPATH, no user site; this tree first on the path), with its file."""
    result = subprocess.run(
        [sys.executable, "-I", "-c", PROBE, str(REPO), *modules],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    files: dict[str, str] = json.loads(result.stdout)
    return files


def _third_party(files: dict[str, str]) -> set[str]:
    return {
        name
        for name in files
        if name.split(".")[0] not in sys.stdlib_module_names and name.split(".")[0] != "supervisord"
    }


def test_the_client_library_loads_only_its_named_modules() -> None:
    """``import supervisord.client`` loads exactly the named set of this package (not the
    safety core, the parser, the VSC's messages or the config), all from this tree, and
    nothing outside the standard library: none of the daemon's dependencies."""
    files = loaded("supervisord.client")
    ours = {name for name in files if name.split(".")[0] == "supervisord"}
    assert ours == CLIENT_MODULES, sorted(ours ^ CLIENT_MODULES)
    assert not _third_party(files), sorted(_third_party(files))
    assert not set(DAEMON_DEPENDENCIES) & {name.split(".")[0] for name in files}
    for name in ours:
        assert Path(files[name]).is_relative_to(REPO / "supervisord"), (name, files[name])


def test_the_client_library_loads_no_safety_module() -> None:
    """SR-8: ``import supervisord.client`` (and with it the typed replies and pushes it
    returns) loads no module of the safety core, checked in a fresh ``python -I -c``."""
    files = loaded("supervisord.client")
    assert "supervisord.api.replies" in files  # the typed vocabulary is what it reads with
    safety = sorted(
        n for n in files if n == "supervisord.safety" or n.startswith("supervisord.safety.")
    )
    assert safety == []


@pytest.mark.parametrize("module", sorted(BRIDGE_MODULES))
def test_the_bridges_pure_modules_load_the_client_set_at_most(module: str) -> None:
    """Each module of the bridge that does not need rclpy loads only bridge modules and the
    client library's named set, and nothing outside the standard library."""
    files = loaded(module)
    ours = {name for name in files if name.split(".")[0] == "supervisord"}
    assert module in ours
    assert ours <= CLIENT_MODULES | BRIDGE_MODULES, sorted(ours - CLIENT_MODULES - BRIDGE_MODULES)
    assert not _third_party(files), sorted(_third_party(files))


def test_the_command_loads_rclpy_only_when_it_runs() -> None:
    """``srcs-ros2 --help`` needs neither rclpy nor the client library: the command's module
    imports the node (and so rclpy) only when asked to run."""
    files = loaded("supervisord.cli.ros2")
    assert "rclpy" not in files
    assert "supervisord.ros2.node" not in files
    assert "supervisord.client" not in files

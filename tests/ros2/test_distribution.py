"""The bridge's own distribution, ``ros2/`` (docs/ros2.md "Install"): a ROS package manifest
whose dependencies are exactly the ROS packages the bridge imports, and a tree of links that
carries the bridge and the client library's named set, nothing else."""

from __future__ import annotations

import ast
import os
import sys
from pathlib import Path
from xml.etree import ElementTree

from supervisord.config import toml
from tests.ros2.test_imports import BRIDGE_MODULES, CLIENT_MODULES, DAEMON_DEPENDENCIES

REPO = Path(__file__).resolve().parents[2]
DISTRIBUTION = REPO / "ros2"
NODE = "supervisord.ros2.node"


def _manifest() -> ElementTree.Element:
    return ElementTree.parse(DISTRIBUTION / "package.xml").getroot()  # noqa: S314 -- ours


def _ros_imports() -> set[str]:
    """The top-level names the bridge's modules import that are neither this package's nor
    the standard library's: the ROS packages it needs."""
    names: set[str] = set()
    for path in (REPO / "supervisord/ros2").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names.add(node.module.split(".")[0])
    return {n for n in names if n not in sys.stdlib_module_names and n != "supervisord"}


def test_manifest_is_an_ament_python_package_of_format_3() -> None:
    """package.xml is format 3, names the package ``srcs_ros2``, builds as ament_python and
    carries srcs-supervisord's version."""
    manifest = _manifest()
    assert manifest.tag == "package"
    assert manifest.get("format") == "3"
    assert manifest.findtext("name") == "srcs_ros2"
    assert manifest.findtext("export/build_type") == "ament_python"
    with (REPO / "pyproject.toml").open("rb") as handle:
        version = toml.load(handle)["project"]["version"]
    assert manifest.findtext("version") == version


def test_manifest_depends_on_exactly_the_ros_packages_the_bridge_imports() -> None:
    """The ``exec_depend``s, which rosdep installs, are the ROS packages the bridge's modules
    import (rclpy and the messages): no more, none missing, and no daemon dependency."""
    manifest = _manifest()
    depends = {e.text for e in manifest.iter() if e.tag.endswith("depend")}
    assert depends == {e.text for e in manifest.iter("exec_depend")}
    imported = _ros_imports()
    assert "rclpy" in imported
    assert depends == imported
    assert not depends & set(DAEMON_DEPENDENCIES)


def test_the_tree_links_the_bridge_and_the_client_set_only() -> None:
    """Every module under ``ros2/supervisord`` is a link to the same file of the repository's
    ``supervisord/``, and together they are the client library's named set, the bridge's pure
    modules and its node: what the client and the bridge load (tests/ros2/test_imports.py)."""
    tree = DISTRIBUTION / "supervisord"
    modules = set()
    files = [
        Path(top, name)
        for top, dirs, names in os.walk(tree, followlinks=True)  # supervisord/ros2 is a link
        if "__pycache__" not in top
        for name in names
        if name.endswith(".py")
    ]
    for path in files:
        relative = path.relative_to(DISTRIBUTION)
        assert path.resolve() == (REPO / relative).resolve(), relative
        assert path.is_symlink() or path.parent.is_symlink(), f"{relative} is a copy, not a link"
        parts = relative.with_suffix("").parts
        modules.add(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    assert modules == CLIENT_MODULES | BRIDGE_MODULES | {NODE}, sorted(
        modules ^ (CLIENT_MODULES | BRIDGE_MODULES | {NODE})
    )
    assert (tree / "py.typed").resolve() == (REPO / "supervisord/py.typed").resolve()

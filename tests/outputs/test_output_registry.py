"""The output registry and the shared pieces of supervisord.outputs.base."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from supervisord.errors import ConfigError
from supervisord.outputs import (
    OutputFault,
    OutputKind,
    OutputUsageError,
    Periodic,
    ReadBack,
    Resources,
    create_output,
    output_class,
    parse_output_spec,
)
from supervisord.outputs.can_enable import CanEnableOutput, CanEnableSpec
from supervisord.outputs.gpio import GpioOutput, GpioSpec
from supervisord.outputs.sim import SimOutput, SimSpec


def _imported_after(code: str) -> set[str]:
    """The top-level modules imported by a fresh interpreter after running ``code``."""
    probe = f"import sys\n{code}\nprint(' '.join(sorted(m.split('.')[0] for m in sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True)
    return set(out.stdout.split())


def test_package_imports_no_plugin() -> None:
    """Importing supervisord.outputs imports neither gpiod nor can."""
    loaded = _imported_after("import supervisord.outputs")
    assert "gpiod" not in loaded
    assert "can" not in loaded


def test_plugin_imported_only_when_chosen() -> None:
    """Choosing the sim kind imports no hardware library; choosing gpio imports gpiod only."""
    sim = _imported_after("import supervisord.outputs as o; o.output_class('sim')")
    assert not {"gpiod", "can"} & sim
    gpio = _imported_after("import supervisord.outputs as o; o.output_class('gpio')")
    assert "gpiod" in gpio
    assert "can" not in gpio


def test_kinds_map_to_classes() -> None:
    """Each kind name maps to its output class."""
    assert output_class("sim") is SimOutput
    assert output_class(OutputKind.GPIO) is GpioOutput
    assert output_class("can") is CanEnableOutput


@pytest.mark.parametrize("table", [{}, {"kind": "relay"}, {"kind": 3}])
def test_unknown_kind_is_a_config_error(table: dict[str, object]) -> None:
    """A missing or unknown kind raises ConfigError naming outputs.NAME.kind."""
    with pytest.raises(ConfigError) as e:
        parse_output_spec("x", table)
    assert e.value.key == "outputs.x.kind"
    with pytest.raises(ConfigError):
        output_class("relay")


def test_prefix_names_the_key() -> None:
    """A caller-given prefix appears in the ConfigError's key."""
    with pytest.raises(ConfigError) as e:
        parse_output_spec("x", {"kind": "sim", "typo": 1}, prefix="robot.outputs.x")
    assert e.value.key == "robot.outputs.x.typo"
    with pytest.raises(ConfigError) as e:
        parse_output_spec(
            "x", {"kind": "gpio", "chip": "c", "line": "17"}, prefix="robot.outputs.x"
        )
    assert e.value.key == "robot.outputs.x.line"


def test_bad_name_is_a_config_error() -> None:
    """An output name with spaces or dots is refused (it becomes part of a cause name)."""
    with pytest.raises(ConfigError):
        SimSpec(name="left wheel")


def test_can_output_needs_a_bus() -> None:
    """create_output refuses a can spec without a bus, and builds the others without one."""
    spec = CanEnableSpec(name="d", arbitration_id=1, data_on=b"\x01", data_off=b"\x00")
    with pytest.raises(ConfigError):
        create_output(spec)
    assert isinstance(create_output(SimSpec(name="s")), SimOutput)


def test_wrong_spec_for_a_class_is_refused() -> None:
    """An output class given another kind's spec raises OutputUsageError."""
    with pytest.raises(OutputUsageError):
        GpioOutput(SimSpec(name="s"))  # type: ignore[arg-type]


def test_readback_refuses_inconsistent_results() -> None:
    """A ReadBack cannot claim success with a differing read-back, nor a mismatch without one."""
    with pytest.raises(ValueError, match="MISMATCH"):
        ReadBack("x", True, True, False)
    with pytest.raises(ValueError, match="MISMATCH"):
        ReadBack("x", True, True, True, OutputFault.MISMATCH)
    assert ReadBack("x", True, True, None).ok
    assert not ReadBack("x", True, True, None, OutputFault.SEND_ERROR).ok


def test_periodic_schedule() -> None:
    """A periodic deadline advances by whole periods and restarts after a late tick."""
    p = Periodic(10)
    assert not p.due(0)
    p.start(100)
    assert (p.deadline, p.due(109), p.due(110)) == (110, False, True)
    p.advance(113)
    assert p.deadline == 120
    p.advance(155)
    assert p.deadline == 165
    p.stop()
    assert not p.due(10**12)
    with pytest.raises(ValueError, match="positive"):
        Periodic(0)


def _imports_of(module: str) -> set[str]:
    """The supervisord.outputs modules ``module``'s source imports, at any depth of it."""
    path = Path(__file__).resolve().parents[2] / "supervisord" / "outputs" / f"{module}.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(
            "supervisord.outputs"
        ):
            found.add(str(node.module))
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("supervisord.outputs")}
    return found


def test_no_import_cycle_between_base_registry_and_plugins() -> None:
    """The base class imports no plugin and not the registry; each plugin imports only the
    base; the registry imports the base and finds the plugins by name."""
    assert _imports_of("base") == set()
    for plugin in ("sim", "gpio", "can_enable"):
        assert _imports_of(plugin) == {"supervisord.outputs.base"}, plugin
    assert _imports_of("registry") == {"supervisord.outputs.base"}


def test_every_spec_names_what_it_holds_exclusively() -> None:
    """SR-11.1: a GPIO spec claims its chip and line, a CAN spec its identifier, a sim spec its
    file; a kernel chip name and its device path are one chip."""
    by_name = GpioSpec(name="a", chip="gpiochip3", line=4).claims()
    by_path = GpioSpec(name="b", chip="/dev/gpiochip3", line=4).claims()
    assert [c.identity for c in by_name] == [c.identity for c in by_path]
    assert by_name[0].option == "line"
    can_claim = CanEnableSpec(name="d", arbitration_id=0x201, data_on=b"\x01", data_off=b"\x00")
    assert [c.identity for c in can_claim.claims()] == [("can", 0x201, False)]
    sim = SimSpec(name="s", path=Path("run/drive"))
    assert [(c.option, c.path) for c in sim.claims()] == [("path", Path("run/drive"))]
    assert SimSpec(name="m").claims() == ()
    assert sim.resolved(Path("/base")).path == Path("/base/run/drive")


def test_every_kind_is_built_the_same_way() -> None:
    """create_output builds every kind through its class's build with the same resources;
    a kind's spec given to another kind's class is refused."""
    spec = SimSpec(name="s")
    built = output_class("sim").build(spec, Resources())
    assert isinstance(built, SimOutput)
    with pytest.raises(OutputUsageError):
        output_class("gpio").build(spec, Resources())

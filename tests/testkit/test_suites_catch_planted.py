"""The kit's conformance suites fail a planted broken link and broken outputs, each on the
check that names its break, and pass the honest implementation they were built from (SR-2.10,
SR-6). The suites also run against every shipped kind: tests/links/test_link_conformance.py
and tests/outputs/test_output_conformance.py."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager

import pytest

from supervisord.links.memory_link import MemoryLink, MemoryPort
from supervisord.outputs import OutputFault
from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.testkit.link_conformance import LinkConformance, LinkHarness
from supervisord.testkit.output_conformance import OutputConformance, OutputHarness
from tests.links.conftest import _serial_harness
from tests.testkit.planted import OffDoesNothingOutput, RaisingLink, SilentFaultOutput


def outcomes(
    suite: object, harness: Callable[[], AbstractContextManager[object]]
) -> dict[str, str]:
    """Every check of ``suite`` on a fresh harness: "passed", or "failed: " and the first
    line of what the check said."""
    found = {}
    for name in sorted(n for n in dir(suite) if n.startswith("test_")):
        with harness() as fresh:
            try:
                getattr(suite, name)(fresh)
            except AssertionError as failure:
                found[name] = "failed: " + (str(failure).splitlines() or [""])[0]
            else:
                found[name] = "passed"
    return found


def failed(found: dict[str, str]) -> dict[str, str]:
    return {name: said for name, said in found.items() if said != "passed"}


def memory_link(kind: type[MemoryLink]) -> Callable[[], AbstractContextManager[LinkHarness]]:
    @contextmanager
    def made() -> Iterator[LinkHarness]:
        port = MemoryPort("vsc0")
        link = kind(port)
        yield _serial_harness(link, "vsc0", port, lambda: True)
        link.close()

    return made


def sim_output(kind: type[SimOutput]) -> Callable[[], AbstractContextManager[OutputHarness]]:
    @contextmanager
    def made() -> Iterator[OutputHarness]:
        out = kind(SimSpec(name="sim"))
        yield OutputHarness(
            out,
            lambda: out.device_level,
            lambda level: out.stick(not level),
            OutputFault.MISMATCH,
            False,
            lambda: out.stick(True),
        )
        out.close()

    return made


def test_the_link_suite_fails_a_link_that_raises_on_a_garbage_byte() -> None:
    """SR-2.10: the link that raises on 0xff 0xff fails the garbage check, saying it raised;
    the memory link it was made from passes every check."""
    assert failed(outcomes(LinkConformance(), memory_link(MemoryLink))) == {}
    broken = failed(outcomes(LinkConformance(), memory_link(RaisingLink)))
    print(broken)  # the report shows what the suite said
    said = broken.pop("test_garbage_never_raises_and_the_link_carries_on")
    assert "RaisingLink.receive raised ValueError" in said, said
    assert "SR-2.10" in said


@pytest.mark.parametrize(
    ("kind", "checks"),
    [
        (OffDoesNothingOutput, {"test_close_leaves_it_off"}),
        (
            SilentFaultOutput,
            {
                "test_fault_is_reported",
                "test_fault_on_off_is_reported",
            },
        ),
    ],
    ids=["off-does-nothing", "silent-fault"],
)
def test_the_output_suite_fails_a_broken_output(kind: type[SimOutput], checks: set[str]) -> None:
    """SR-6: an output left on by its release, and one that reports writes it never read
    back, each fail the checks that name their break, and only those; the sim output they
    were made from passes every check."""
    assert failed(outcomes(OutputConformance(), sim_output(SimOutput))) == {}
    broken = failed(outcomes(OutputConformance(), sim_output(kind)))
    print(broken)  # the report shows what the suite said
    assert set(broken) == checks, broken

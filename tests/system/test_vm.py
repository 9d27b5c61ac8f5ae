"""The system tier's measure of a busy host: the time qemu waited for a CPU (``vm.py``).

A guest that the host holds back misses its own deadlines, so the tier reads that time from
the host's kernel and says so beside a failure (docs/system-tier.md "A busy host"). Here the
reading is taken from a real process kept waiting, and the figures from made-up samples.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.testkit.wait import wait_until
from tests.system.vm import STARVED_S, Starvation, starvation_text, starved

BUSY = "while True: pass"


@pytest.fixture
def two_on_one_cpu() -> Iterator[subprocess.Popen[bytes]]:
    """Two busy processes on the same CPU: each waits for it while the other runs."""
    cpu = min(os.sched_getaffinity(0))
    busy = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(2)]
    try:
        for process in busy:
            os.sched_setaffinity(process.pid, {cpu})
        yield busy[0]
    finally:
        for process in busy:
            process.kill()
            process.wait()


@pytest.mark.skipif(
    not Path("/proc/self/schedstat").exists(), reason="the kernel keeps no schedstats"
)
def test_the_wait_for_a_cpu_is_read_from_the_kernel(
    two_on_one_cpu: subprocess.Popen[bytes],
) -> None:
    """SR-9: a process that shares its one CPU with another busy one is runnable but not
    running part of the time, and ``Starvation`` reads that wait from ``schedstat``: it grows;
    a process that no longer exists reads as not measured."""
    meter = Starvation(two_on_one_cpu.pid)
    meter.sample()

    def waited() -> bool:
        meter.sample()
        return meter.lost_s() > 0.05

    wait_until(waited, what="a wait for the CPU")
    assert meter.samples[-1][1] > meter.samples[0][1]
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    assert Starvation(gone.pid).waited_s() is None


def test_a_scenario_is_starved_when_held_back_half_a_second_within_one() -> None:
    """SR-9: over a scenario the figures are the time held back, its share and the most
    within any one second; 0.5 s or more within one second is a starved guest (longer than
    its 1 s link loss and 700 ms proof test allow), spread thinly it is not."""
    meter = Starvation(0)
    # 10 s sampled every 0.25 s: 0.05 s lost per sample, and 0.6 s more between 4.0 and 4.75.
    waited = 0.0
    for i in range(41):
        t = i * 0.25
        meter.samples.append((t, waited))
        waited += 0.05 + (0.2 if 4.0 <= t < 4.75 else 0.0)
    figures = meter.between(0.0, 10.0)
    assert figures is not None
    assert figures["held back s"] == pytest.approx(2.6)
    assert figures["share"] == pytest.approx(0.26)
    assert figures["most in one second s"] == pytest.approx(0.8)
    assert starved(figures)
    assert "2.6 s of 10.0 s (26 %), at most 0.8 s within one second" in starvation_text(figures)
    thin = meter.between(6.0, 10.0)
    assert thin is not None
    assert thin["most in one second s"] == pytest.approx(0.2)
    assert thin["most in one second s"] < STARVED_S
    assert not starved(thin)
    assert meter.between(20.0, 30.0) is None
    assert not starved(None)
    assert starvation_text(None).startswith("not measured")

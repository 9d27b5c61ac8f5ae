"""The host side of the system tier: boot the guest, collect its results, cut its power.

Five boots (each about 2-8 s before the scenarios start):

1. ``srcs.suite=main``: systemd as PID 1 runs the scenarios in ``guest/scenarios.py`` against
   ``srcsd@`` from the package (``--deb``), which they install with ``dpkg -i`` in the guest,
   then reboots (qemu exits).
2. ``srcs.suite=powercut``: the stop record lives on a virtual ext4 disk; a client in the guest
   prints every record the daemon pushes to it (``SRCS-ACK``) while transitions are driven in
   a burst; after ``--acks`` of them this process kills qemu with SIGKILL: a power cut.
3. ``srcs.mode=run``: a plain boot mounts the disk (ext4 replays its journal, as after a real
   power cut) and checks every acknowledged record against what is on the disk.
4. ``srcs.suite=reboot-install``: the overlay's writable layer on a second virtual disk
   (``srcs.upper=``), so what the guest installs survives; the robot of the bringup scenarios
   (guest/bringup.py) installed and enabled, brought to RUN, then a clean ``systemctl
   reboot``. qemu exits at the reset (``-no-reboot``) and is started again on the same disk:
   the same machine coming back up.
5. ``srcs.suite=reboot-check``: the default target (``multi-user.target``), as a robot boots:
   the enabled units come up on their own and the scenario checks their order and a takeover.

The guest reports with console lines ``SRCS-PLAN name ...``, ``SRCS-START {json}`` and
``SRCS-RESULT {json}``; a planned scenario without a result counts as failed. Only the
standard library is used: this runs with the system's python3.

A busy host slows the emulated guest: qemu's threads wait in the host's run queue, and the
guest, whose clock follows the host's, sees its own processes wake late. ``Starvation``
reads that wait from the kernel (``/proc/PID/task/TID/schedstat``: the time each thread was
runnable but not running) four times a second. A boot's budget grows by the time the guest
was held back (up to three times the budget), and every scenario's result says how much of
its time the guest was held back and the longest stretch; a failure while the guest was
starved says so plainly, beside the failure (docs/system-tier.md "A busy host").
"""

from __future__ import annotations

import argparse
import json
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

PLAN = "SRCS-PLAN "
START = "SRCS-START "
RESULT = "SRCS-RESULT "
ACK = "SRCS-ACK "
RC = "SRCS-VM-RC="
ACKED_FILE = "acked.jsonl"
GUEST_TMP = Path("/tmp")  # noqa: S108 - the guest mounts a fresh tmpfs here (tests/system/init)
SAMPLE_S = 0.25  # how often qemu's run-queue wait is read
STARVED_S = 0.5
"""Held back this long within one second, the guest misses deadlines of its own: the tier's
link-loss deadline is 1 s and the proof test's 700 ms (docs/system-tier.md)."""
ROOT_DEVICE = "/dev/vda"  # the one virtual disk of a boot (tests/system/init, srcs.upper=)
BUDGET_GROWTH_LIMIT = 3.0  # a boot's budget grows with the starvation up to this factor
BUDGET_S = 2400  # a scenario boot's guest time (docs/system-tier.md "A busy host")
JUDGED_BUDGET_S = 3000  # judged: the monitors' and the verdicts' cost (docs/system-tier.md)


class Starvation:
    """How long qemu was runnable but not running on the host: the guest's lost time.

    Samples are (host monotonic s, run-queue wait s summed over qemu's threads). The kernel
    keeps the wait per thread in ``schedstat`` (its second field, ns) when it keeps schedstats
    at all; without it every figure is ``None`` and nothing is claimed."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.samples: list[tuple[float, float]] = []

    def waited_s(self) -> float | None:
        total = 0
        try:
            for task in Path(f"/proc/{self.pid}/task").iterdir():
                try:
                    total += int((task / "schedstat").read_text().split()[1])
                except (OSError, IndexError, ValueError):
                    continue  # a thread that just ended
        except OSError:
            return None
        return total / 1e9

    def sample(self) -> None:
        waited = self.waited_s()
        if waited is not None:
            self.samples.append((time.monotonic(), waited))

    def lost_s(self) -> float:
        """The guest's time lost so far (what the budget grows by)."""
        return self.samples[-1][1] - self.samples[0][1] if len(self.samples) > 1 else 0.0

    def between(self, start: float, end: float) -> dict[str, float] | None:
        """Over [start, end] (host monotonic s): the wait, its share, and the most the guest
        was held back within any one second; ``None`` without samples there."""
        inside = [(t, w) for t, w in self.samples if start <= t <= end]
        if len(inside) < 2:
            return None
        worst = 0.0
        for i, (t, w) in enumerate(inside):
            later = [w2 for t2, w2 in inside[i:] if t2 - t <= 1.0 + SAMPLE_S / 2]
            worst = max(worst, min(later[-1] - w, 1.0))  # the window is a second, give or take
        span = inside[-1][0] - inside[0][0]
        waited = inside[-1][1] - inside[0][1]
        return {
            "held back s": round(waited, 1),
            "of s": round(span, 1),
            # Two threads that wait at once count twice: at most the whole span.
            "share": round(min(waited / span, 1.0), 2) if span > 0 else 0.0,
            "most in one second s": round(worst, 2),
        }


def starvation_text(figures: dict[str, float] | None) -> str:
    if figures is None:
        return "not measured (no schedstat for qemu's threads)"
    return (
        f"{figures['held back s']} s of {figures['of s']} s ({100 * figures['share']:.0f} %), "
        f"at most {figures['most in one second s']} s within one second"
    )


HOST_TOO_SLOW = (
    f"THE HOST WAS TOO SLOW: it held the guest back {STARVED_S} s or more within one second "
    "during this scenario, longer than the guest's own deadlines allow; this failure may be "
    "the busy host's, not the product's"
)


def starved(figures: dict[str, float] | None) -> bool:
    return figures is not None and figures["most in one second s"] >= STARVED_S


@dataclass
class Boot:
    """What one boot printed and how it ended."""

    wall_s: float
    killed: bool = False
    plan: list[str] = field(default_factory=list)
    starts: dict[str, float] = field(default_factory=dict)  # scenario -> host monotonic s
    results: list[dict[str, Any]] = field(default_factory=list)
    acks: list[dict[str, Any]] = field(default_factory=list)
    rc: int | None = None
    starvation: Starvation | None = None
    ended: float | None = None  # host monotonic s

    def held_back(self, name: str, end: float | None = None) -> dict[str, float] | None:
        """The starvation over scenario ``name``: from its start line to its result (or to
        ``end``, else the end of the boot, when it gave none)."""
        start = self.starts.get(name)
        if self.starvation is None or start is None:
            return None
        result = next((r for r in self.results if r.get("name") == name), None)
        stop = result.get("host_end") if result is not None else None
        stop = stop or end or self.ended or time.monotonic()
        return self.starvation.between(start, stop)


class Vm:
    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args

    def command(self, append: str, *, disk: str | None) -> list[str]:
        a = self.args
        cmd = [
            "qemu-system-x86_64",
            *("-nodefaults", "-no-user-config", "-accel", "tcg", "-cpu", "max"),
            *("-smp", "1", "-m", "1024", "-display", "none", "-serial", "stdio"),
            # A reset is how the guest ends (init and the test unit reboot), and qemu then exits.
            "-no-reboot",
            *("-device", "virtio-rng-pci", "-kernel", a.kernel, "-initrd", a.initrd),
            # multidevs=remap: / spans several host file systems whose inode numbers collide.
            "-virtfs",
            "local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap",
            "-virtfs",
            f"local,path={a.out},mount_tag=srcs_out,security_model=none,multidevs=remap",
        ]
        if disk is not None:
            # cache=writeback: what the guest flushed has been written to the image file, and
            # what it did not flush may still be in the guest's page cache, lost with qemu.
            cmd += ["-drive", f"file={disk},format=raw,if=virtio,cache=writeback"]
        # dummy_hcd.num=2: two USB device controllers for the usb scenarios' gadgets.
        append = f"console=ttyS0 panic=-1 quiet dummy_hcd.num=2 srcs.deb={a.deb} srcs.out {append}"
        if Path(a.repo).is_relative_to(GUEST_TMP):  # the guest's /tmp is its own: keep the repo
            append = f"srcs.keep={a.repo} {append}"
        return [*cmd, "-append", append]

    def boot(
        self,
        append: str,
        *,
        disk: str | None = None,
        timeout: float,
        kill_when: Callable[[Boot], bool] | None = None,
    ) -> Boot:
        started = time.monotonic()
        result = Boot(wall_s=0.0)
        proc = subprocess.Popen(
            self.command(append, disk=disk),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
        )
        assert proc.stdout is not None
        buffer = b""
        starvation = Starvation(proc.pid)
        result.starvation = starvation
        starvation.sample()
        said = 0.0  # when the console was last told of a starved second
        while True:
            # The budget is the guest's time: what the host held it back for comes on top.
            budget = timeout + min(starvation.lost_s(), (BUDGET_GROWTH_LIMIT - 1) * timeout)
            left = started + budget - time.monotonic()
            if left <= 0:
                print(
                    f"[host] the guest ran past {budget:.0f} s ({timeout:.0f} s, and "
                    f"{budget - timeout:.0f} s that the host held it back): killing qemu; "
                    f"held back {starvation_text(starvation.between(started, time.monotonic()))}",
                    flush=True,
                )
                proc.kill()
                break
            ready, _, _ = select.select([proc.stdout], [], [], min(left, SAMPLE_S))
            starvation.sample()
            said = self._say_starved(starvation, started, said)
            if not ready:
                continue
            chunk = os.read(proc.stdout.fileno(), 65536)
            if not chunk:
                break
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            for raw in lines:
                self._line(raw.decode(errors="replace").rstrip("\r"), started, result)
            if kill_when is not None and not result.killed and kill_when(result):
                # The power cut: no shutdown, no flush; the guest simply stops existing.
                os.kill(proc.pid, signal.SIGKILL)
                result.killed = True
                print(f"[host {time.monotonic() - started:7.2f}] qemu killed", flush=True)
        proc.wait()
        result.ended = time.monotonic()
        result.wall_s = result.ended - started
        print(f"[host {result.wall_s:7.2f}] qemu exited ({proc.returncode})", flush=True)
        return result

    @staticmethod
    def _say_starved(starvation: Starvation, started: float, said: float) -> float:
        """Tell the console, beside the guest's own lines, when the host held the guest back
        for ``STARVED_S`` or more within the last second (at most every 5 s)."""
        now = time.monotonic()
        last = starvation.between(now - 1.0, now)
        if now - said < 5.0 or not starved(last):
            return said
        assert last is not None
        print(
            f"[host {now - started:7.2f}] the host held the guest back "
            f"{last['most in one second s']} s in the last second",
            flush=True,
        )
        return now

    @staticmethod
    def _line(line: str, started: float, result: Boot) -> None:
        if not line.strip():
            return
        print(f"[host {time.monotonic() - started:7.2f}] {line}", flush=True)
        at = line.find(PLAN)
        if at >= 0:
            result.plan.extend(line[at + len(PLAN) :].split())
            return
        at = line.find(START)
        if at >= 0:
            try:
                result.starts[json.loads(line[at + len(START) :])["name"]] = time.monotonic()
            except (json.JSONDecodeError, KeyError, TypeError):
                print("[host] unreadable start line above", flush=True)
            return
        for marker, into in ((RESULT, result.results), (ACK, result.acks)):
            at = line.find(marker)
            if at >= 0:
                try:
                    into.append(json.loads(line[at + len(marker) :]))
                except json.JSONDecodeError:
                    print("[host] unreadable result line above", flush=True)
                    return
                if marker == RESULT and isinstance(into[-1], dict):
                    into[-1]["host_end"] = time.monotonic()
                return
        at = line.find(RC)
        if at >= 0:
            result.rc = int(line[at + len(RC) :].split(maxsplit=1)[0])


def systemd_boot(vm: Vm, suite: str, unit: str = "srcs-system-tier.target") -> str:
    a = vm.args
    prep = Path(a.repo, "tests/system/guest/prep")
    chosen = f" srcs.scenarios={a.scenarios}" if a.scenarios and suite == "main" else ""
    judged = " srcs.judge" if a.judge else ""
    return (
        f"srcs.mode=systemd srcs.prep={prep} systemd.unit={unit} "
        f"srcs.suite={suite} srcs.repo={a.repo} srcs.python={a.python}{chosen}{judged}"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    for name in ("repo", "kernel", "initrd", "deb", "disk", "root-disk", "out", "python"):
        parser.add_argument(f"--{name}", required=True)
    parser.add_argument("--started", type=float, default=time.time())
    parser.add_argument("--acks", type=int, default=40, help="records acknowledged before the cut")
    parser.add_argument(
        "--only", choices=("main", "powercut", "reboot"), help="one part of the tier"
    )
    parser.add_argument(
        "--scenarios", help="comma-separated names: only these of the main boot (install runs)"
    )
    parser.add_argument(
        "--judge",
        action="store_true",
        help="the kernel has the rtapp monitors: judge every scenario (guest/judge.py)",
    )
    args = parser.parse_args()
    vm = Vm(args)
    outcomes: dict[str, bool] = {}

    boots: list[Boot] = []
    if args.only in (None, "main"):
        boots.append(scenario_boot(vm, systemd_boot(vm, "main"), "main-suite", outcomes))
    if args.only in (None, "powercut"):
        outcomes["powercut"] = power_cut(vm)
    if args.only in (None, "reboot"):
        boots += reboot(vm, outcomes)

    print("\n== system tier", flush=True)
    starved_failures = [name for boot in boots for name in report(boot, outcomes)]
    print(f"total time {time.time() - args.started:.0f} s", flush=True)
    passed = sum(outcomes.values())
    failed = len(outcomes) - passed
    if starved_failures:
        print(
            f"{len(starved_failures)} of the {failed} failed while the host held the guest "
            f"back: {', '.join(starved_failures)}. Run the tier again on a quieter host before "
            "reading them as the product's",
            flush=True,
        )
    print(f"{passed} passed, {failed} failed", flush=True)
    return 1 if failed else 0


def scenario_boot(
    vm: Vm, append: str, suite: str, outcomes: dict[str, bool], *, disk: str | None = None
) -> Boot:
    """A boot whose guest plans scenarios and reports each: every planned one without a result
    counts as failed, and a boot that planned nothing fails as ``suite``."""
    boot = vm.boot(append, disk=disk, timeout=JUDGED_BUDGET_S if vm.args.judge else BUDGET_S)
    for name in boot.plan:
        outcomes[name] = False
    for result in boot.results:
        outcomes[result["name"]] = bool(result["ok"])
    if not boot.plan:
        outcomes[suite] = False
        print(f"FAIL {suite}: the guest planned no scenario", flush=True)
    return boot


def reboot(vm: Vm, outcomes: dict[str, bool]) -> list[Boot]:
    """Boots 4 and 5 on one disk: the robot installed, enabled and in RUN, a clean reboot,
    and the same machine booted again to its default target."""
    disk = vm.args.root_disk
    before = scenario_boot(
        vm,
        systemd_boot(vm, "reboot-install") + f" srcs.upper={ROOT_DEVICE}",
        "reboot-install",
        outcomes,
        disk=disk,
    )
    if not before.results or not all(r["ok"] for r in before.results):
        return [before]  # nothing was left to boot again
    after = scenario_boot(
        vm,
        systemd_boot(vm, "reboot-check", unit="multi-user.target") + f" srcs.upper={ROOT_DEVICE}",
        "reboot-check",
        outcomes,
        disk=disk,
    )
    return [before, after]


def report(boot: Boot, outcomes: dict[str, bool]) -> list[str]:
    """Print a boot's results, each with the time the host held the guest back, and its planned
    scenarios that gave none; returns the failed ones during which the guest was starved."""
    starved_failures = []
    for result in boot.results:
        print(f"{'PASS' if result['ok'] else 'FAIL'} {result['name']}: {result['detail']}")
        for key, value in result.get("measured", {}).items():
            print(f"    {key}: {value}")
        held = boot.held_back(result["name"])
        print(f"    the host held the guest back: {starvation_text(held)}")
        if not result["ok"] and starved(held):
            starved_failures.append(result["name"])
            print(f"    {HOST_TOO_SLOW}")
    for name in boot.plan:
        if not outcomes.get(name) and not any(r["name"] == name for r in boot.results):
            print(f"FAIL {name}: no result from the guest")
            held = boot.held_back(name)
            if held is not None:
                print(f"    the host held the guest back: {starvation_text(held)}")
                if starved(held):
                    starved_failures.append(name)
                    print(f"    {HOST_TOO_SLOW}")
    return starved_failures


def power_cut(vm: Vm) -> bool:
    """Boots 2 and 3: records acknowledged to a client before the cut must be on the disk."""
    out = Path(vm.args.out)
    burst = vm.boot(
        systemd_boot(vm, "powercut"),
        disk=vm.args.disk,
        timeout=600,
        kill_when=lambda boot: len(boot.acks) >= vm.args.acks,
    )
    problems = [r["detail"] for r in burst.results if not r["ok"]]
    held = burst.starvation.between(0, burst.ended or 0) if burst.starvation else None
    print(f"powercut burst: the host held the guest back: {starvation_text(held)}", flush=True)
    if not burst.killed:
        print(f"FAIL powercut: only {len(burst.acks)} acknowledged records, no cut", flush=True)
        return False
    with (out / ACKED_FILE).open("w") as handle:
        for record in burst.acks:
            handle.write(json.dumps(record) + "\n")
    check = vm.boot(
        f"srcs.mode=run -- env PYTHONPATH={vm.args.repo} {vm.args.python} "
        f"{vm.args.repo}/tests/system/guest/scenarios.py "
        f"powercut-check /srcs-out/{ACKED_FILE}",
        disk=vm.args.disk,
        timeout=300,
    )
    verdicts = [r for r in check.results if r["name"] == "powercut"]
    ok = bool(verdicts) and all(r["ok"] for r in verdicts) and not problems
    for r in verdicts:
        print(f"{'PASS' if r['ok'] else 'FAIL'} powercut: {r['detail']}", flush=True)
        for key, value in r.get("measured", {}).items():
            print(f"    {key}: {value}", flush=True)
    if not verdicts:
        print("FAIL powercut: the check boot gave no result", flush=True)
    if not ok and starved(held):
        print(f"    {HOST_TOO_SLOW}", flush=True)
    return ok


if __name__ == "__main__":
    sys.exit(main())

"""The acknowledged fleet stop, measured: from the console's send to the last robot's
acknowledgement, with real robots and with a load generator of simulated agents, and with
packet loss (SR-13.15, docs/fleet.md "The fleet stop: figures").

Run: ``.venv/bin/python -m bench.fleet_stop [--robots 5] [--sims 1000] [--rounds 20]``
(root: it runs in a network namespace of its own, loopback only, where ``tc`` may add loss).

- **The parts**: a real mosquitto with the fleet's mutual TLS and ACL, ``--robots`` real
  ``srcsd`` against ``srcs-sim`` (armed once: the first round stops them from RUN, the later
  ones are answered from STOPPED, each a full ``fleet_stop`` that writes the outputs off again
  and reads them back), a real ``srcs-fleet-agent`` process per robot, and the console's own
  code (``srcsctl fleet stop --all --json``) in this process.
- **Measured** per round: the console's time from its first publish to the last conclusive
  acknowledgement (``ms`` of its summary), and whether every robot answered; p50/p95/p99 over
  the rounds. Then the same with ``--sims`` simulated agents (``bench.fleet_sim_agents``, one
  process) beside the robots. Then with ``netem loss`` on loopback (every link: the robots',
  the console's, the broker's): each round's robots that answered, the ones named silent,
  and how long after the deadline the verdict came (the rule: within 1 s).
- Not asserted: figures of a shared 2-core machine.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from statistics import quantiles

from bench.netns import in_namespace
from supervisord.cli import srcsctl
from supervisord.fleet_agent.acl import acl_text, broker_conf
from supervisord.testkit.robot import OutputDef, Robot
from tests.fleet_agent.agents import running_agents
from tests.fleet_agent.broker import FLEET, Broker, free_port, pki

REPO = Path(__file__).resolve().parent.parent
OUTPUTS = (OutputDef("drive"), OutputDef("lights", role="power"))


def stop_round(broker: Broker, deadline: float) -> dict[str, object]:
    keys = broker.pki
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        srcsctl.main(
            [
                "fleet", "stop", "--all", "--json", "--deadline", str(deadline),
                "--fleet", FLEET, "--broker", f"127.0.0.1:{broker.port}",
                "--cafile", str(keys / "ca.pem"), "--cert", str(keys / "console-1.pem"),
                "--key", str(keys / "console-1.key"), "--name", "console-1",
            ]
        )  # fmt: skip
    rows = [json.loads(line) for line in out.getvalue().splitlines() if line.strip()]
    if not rows:  # the console did not reach the broker within its 5 s (said on stderr)
        return {"ms": None, "all": False, "robots": 0, "silent": [], "not_stopped": []}
    summary = rows[-1]
    robots = [r for r in rows[:-1] if "robot" in r]
    return {
        "ms": summary.get("ms"),
        "all": summary.get("all_answered"),
        "robots": len(robots),
        "silent": sorted(r["robot"] for r in robots if r["result"] == "silent"),
        "not_stopped": sorted(
            r["robot"] for r in robots if r["result"] not in ("stopped", "silent")
        ),
    }


def add_loss(percent: float) -> str:
    """Lose ``percent`` of loopback's packets: netem where the kernel has it, else nftables
    dropping at the input hook at random (this machine's kernel has no netem); every link
    (robots', console's, broker's) is loopback here."""
    netem = ["tc", "qdisc", "add", "dev", "lo", "root", "netem", "loss", f"{percent:g}%"]
    if subprocess.run(netem, check=False, capture_output=True).returncode == 0:
        return "netem"
    if shutil.which("nft") is None:
        raise SystemExit("no netem in this kernel and no nft (apt-get install nftables)")
    rules = (
        "table inet srcs_loss {\n chain input {\n  type filter hook input priority 0;\n"
        f"  numgen random mod 1000 < {round(percent * 10)} drop\n }}\n}}\n"
    )
    subprocess.run(["nft", "-f", "-"], input=rules, text=True, check=True)
    return "nftables numgen at the input hook, netem missing"


def remove_loss() -> None:
    subprocess.run(["tc", "qdisc", "del", "dev", "lo", "root"], check=False, capture_output=True)
    subprocess.run(
        ["nft", "delete", "table", "inet", "srcs_loss"], check=False, capture_output=True
    )


def percentiles(values: list[float]) -> str:
    if len(values) < 2:
        return f"n={len(values)} {values}"
    cuts = quantiles(values, n=100, method="inclusive")
    p50, p95, p99 = cuts[49], cuts[94], cuts[98]
    return f"n={len(values)} p50 {p50:.1f}, p95 {p95:.1f}, p99 {p99:.1f}, max {max(values):.1f} ms"


def rounds(broker: Broker, count: int, deadline: float, label: str) -> None:
    done = [stop_round(broker, deadline) for _ in range(count)]
    answered = [float(r["ms"]) for r in done if r["all"]]  # type: ignore[arg-type]
    print(f"{label}: robots per round {done[0]['robots']}; every robot answered in "
          f"{len(answered)} of {count} rounds")  # fmt: skip
    print(f"  send to last ack: {percentiles(answered)}")


def _lossy(broker: Broker, loss: float, count: int, deadline: float) -> None:
    """Rounds with ``loss`` percent of loopback's packets lost: who answered, who was named
    silent, and how long after the deadline the verdict came."""
    print(f"with {loss:g}% loss on loopback ({add_loss(loss)}), deadline {deadline} s:")
    late = []
    for i in range(count):
        r = stop_round(broker, deadline)
        if r["ms"] is None:
            print(f"  round {i + 1}: the console did not reach the broker within 5 s")
            continue
        late.append(float(r["ms"]) / 1000 - deadline)  # type: ignore[arg-type]
        answered = r["robots"] - len(r["silent"])  # type: ignore[operator, arg-type]
        print(
            f"  round {i + 1}: answered {answered}/{r['robots']} in {r['ms']} ms; "
            f"silent named: {_names(r['silent'])}; not stopped: {_names(r['not_stopped'])}"
        )
    worst = f"{max(late) * 1000:.0f} ms" if late else "-"
    print(f"  verdict after the deadline: at most {worst} (early rounds: negative)")


def _names(names: object) -> str:
    listed = list(names) if isinstance(names, list) else []
    more = f" and {len(listed) - 5} more" if len(listed) > 5 else ""
    return ", ".join(listed[:5]) + more if listed else "-"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=5)
    parser.add_argument("--sims", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--loss", type=float, default=10.0, help="percent lost under netem")
    parser.add_argument("--deadline", type=float, default=2.0)
    args = parser.parse_args(argv)
    in_namespace("bench.fleet_stop")
    names = [f"robot-{i + 1}" for i in range(args.robots)]
    with contextlib.ExitStack() as stack:
        work = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="fleet-stop-")))
        keys = pki(work / "pki", [*names, "console-1", "sim"])
        acl = acl_text(FLEET, {n: frozenset() for n in names}, ["console-1"])
        # The load generator's one name (bench.fleet_sim_agents): a bench's rule only.
        acl += "".join(
            f"{line}\n"
            for line in (
                "user sim",
                f"topic read srcs/{FLEET}/stop/all",
                f"topic write srcs/{FLEET}/ack/+",
                f"topic write srcs/{FLEET}/robot/+",
            )
        )
        (work / "acl").write_text(acl)
        port = free_port()
        config = work / "mosquitto.conf"
        config.write_text(
            broker_conf(port, str(keys), str(work / "acl"), bind="127.0.0.1")
            + "user root\npersistence false\nmax_queued_messages 10000\n"
        )
        broker = Broker(port, keys, config=config)
        broker.start()
        stack.callback(broker.stop)
        robots = {}
        for name in names:
            (work / name).mkdir()
            fleet = f"[fleet]\nagent_uid = {os.getuid()}\n"
            robot = stack.enter_context(Robot(work / name, outputs=OUTPUTS, extra_toml=fleet))
            robots[name] = robot
        stack.enter_context(
            running_agents(broker, {n: r.socket_path for n, r in robots.items()}, work)
        )
        for robot in robots.values():
            robot.arm()
        print(f"{args.robots} real robots (srcsd + srcs-sim + srcs-fleet-agent), "
              f"mosquitto with mTLS, {os.cpu_count()} CPUs")  # fmt: skip
        first = stop_round(broker, 10.0)
        off = all(r.output_file("drive") is False for r in robots.values())
        print(f"from RUN: {first['ms']} ms to the last ack, every output off: {off}, "
              f"not stopped: {first['not_stopped']}")  # fmt: skip
        rounds(broker, args.rounds, args.deadline, f"{args.robots} robots")

        if args.sims:
            sims = subprocess.Popen(
                [sys.executable, "-m", "bench.fleet_sim_agents", "--count", str(args.sims),
                 "--broker", f"127.0.0.1:{port}", "--pki", str(keys), "--fleet", FLEET],
                stdout=subprocess.PIPE, text=True, cwd=REPO,
            )  # fmt: skip
            stack.callback(sims.wait, 30)
            stack.callback(sims.terminate)
            ready = sims.stdout.readline().split() if sims.stdout else []
            print(f"simulated agents connected: {ready[-1] if ready else '?'} of {args.sims}")
            rounds(
                broker,
                args.rounds,
                max(args.deadline, 5.0),
                f"{args.robots} robots + {args.sims} simulated agents",
            )
            sims.terminate()
            sims.wait(30)
            time.sleep(2)

        if args.loss > 0:
            stack.callback(remove_loss)
            _lossy(broker, args.loss, args.rounds, args.deadline)
    return 0


if __name__ == "__main__":
    sys.exit(main())

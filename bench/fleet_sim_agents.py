"""The fleet stop bench's load generator: many simulated agents in one process (a part
``bench.fleet_stop`` starts, not a bench).

Each is one MQTT client with the load generator's one certificate (CN ``sim``; the ACL lets
``sim`` read the fleet's ``stop/all`` and write the ``ack`` and presence topics: a bench's
rule, never a fleet's): it announces its presence (retained, with a will), subscribes to
``stop/all`` and answers each stop at once with an acknowledgement (state STOPPED, no outputs,
no record: its name ``sim-NNNNN`` says it is simulated). Clients are spread over ``--threads``
threads, each running its clients' network loops with one ``select`` over their sockets (paho's
``loop_read``, ``loop_write``, ``loop_misc``), because a thread per client would not reach
1,000 here.

    python -m bench.fleet_sim_agents --count 1000 --broker 127.0.0.1:PORT --pki DIR --fleet F
"""

from __future__ import annotations

import argparse
import json
import select
import signal
import ssl
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion

from supervisord.fleet_agent import ack as acks
from supervisord.fleet_agent import message
from supervisord.fleet_agent.topics import ALL, ack_topic, presence_topic, stop_topic


def _client(name: str, fleet: str, pki: Path, connected: list[str]) -> mqtt.Client:
    client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=name, clean_session=True)
    client.tls_set(
        ca_certs=str(pki / "ca.pem"),
        certfile=str(pki / "sim.pem"),
        keyfile=str(pki / "sim.key"),
        cert_reqs=ssl.CERT_REQUIRED,
        tls_version=ssl.PROTOCOL_TLS_CLIENT,
    )
    presence = {"v": 1, "robot": name, "groups": ["sim"]}
    client.will_set(presence_topic(fleet, name), json.dumps({**presence, "online": False}), 1, True)

    def on_connect(c: mqtt.Client, u: object, f: object, reason: object, p: object) -> None:
        c.subscribe(stop_topic(fleet, ALL), 1)
        c.publish(presence_topic(fleet, name), json.dumps({**presence, "online": True}), 1, True)
        connected.append(name)

    def on_message(c: mqtt.Client, u: object, msg: mqtt.MQTTMessage) -> None:
        parsed = message.parse(bytes(msg.payload))
        if isinstance(parsed, message.Refused):
            return
        reply: dict[str, object] = {"state": "STOPPED", "outputs": [], "record_seq": None}
        answer = acks.from_reply(name, parsed.kind, parsed.stop_id, reply, 0.0)
        c.publish(ack_topic(fleet, name), answer.encode(), 1, False)

    client.on_connect = on_connect
    client.on_message = on_message
    return client


def _run(clients: list[mqtt.Client], stop: threading.Event) -> None:
    while not stop.is_set():
        socks = {}
        for c in clients:
            s = c.socket()
            if s is not None:
                socks[s] = c
        if not socks:
            time.sleep(0.1)
            continue
        want_write = [s for s, c in socks.items() if c.want_write()]
        readable, writable, _ = select.select(list(socks), want_write, [], 0.2)
        for s in readable:
            socks[s].loop_read()
        for s in writable:
            socks[s].loop_write()
        for c in clients:
            c.loop_misc()


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--threads", type=int, default=8)
    parser.add_argument("--broker", required=True)
    parser.add_argument("--pki", type=Path, required=True)
    parser.add_argument("--fleet", required=True)
    args = parser.parse_args(argv)
    host, _, port = args.broker.rpartition(":")
    connected: list[str] = []
    clients = []
    for i in range(args.count):
        client = _client(f"sim-{i:05d}", args.fleet, args.pki, connected)
        try:
            client.connect(host, int(port), keepalive=60)
        except OSError as error:  # e.g. out of descriptors: say how many there are
            print(f"sim agents: {i} connected, then {error}", file=sys.stderr)
            break
        clients.append(client)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    done = threading.Event()
    threads = [
        threading.Thread(target=_run, args=(clients[i :: args.threads], done), daemon=True)
        for i in range(args.threads)
    ]
    for t in threads:
        t.start()
    deadline = time.monotonic() + 120
    while len(connected) < len(clients) and time.monotonic() < deadline and not stop.is_set():
        time.sleep(0.2)
    print(f"ready {len(connected)}", flush=True)
    stop.wait()
    for i, c in enumerate(clients):  # no presence left behind: later rounds are not for them
        c.publish(presence_topic(args.fleet, f"sim-{i:05d}"), b"", 1, True)
    time.sleep(3)  # the network threads send the deletions
    done.set()
    for c in clients:
        c.disconnect()
    return 0


if __name__ == "__main__":
    sys.exit(main())

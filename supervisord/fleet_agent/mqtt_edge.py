"""The fleet's MQTT connection: the one module of the agent and the console that imports the
client library, ``paho-mqtt`` (an optional dependency: the robot's supervisor never needs it;
docs/fleet.md "The fleet stop").

Mutual TLS (SR-13.13): the broker's certificate is checked against the fleet's CA, with its
host name, and this end shows its own certificate, whose CN is its name at the broker
(mosquitto's ``use_identity_as_username``): the ACL file (:mod:`.acl`) gives that name its
topics and no others. TLS 1.2 at least. QoS 1 both ways, clean sessions (a stop queued for
a robot that was away would arrive stale, and the replay window would refuse it anyway).
Messages are handed to the caller's queue from paho's network thread; the caller publishes
from its own thread (paho's ``publish`` is thread-safe).
"""

from __future__ import annotations

import contextlib
import queue
import socket
import ssl
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
from paho.mqtt.properties import Properties
from paho.mqtt.reasoncodes import ReasonCode


@dataclass(frozen=True, slots=True)
class Tls:
    cafile: Path
    certfile: Path
    keyfile: Path


@dataclass(frozen=True, slots=True)
class Incoming:
    topic: str
    payload: bytes
    retained: bool
    arrived: float  # time.monotonic() when paho handed it over


@dataclass(frozen=True, slots=True)
class Will:
    topic: str
    payload: bytes


class Connection:
    """A client that keeps reconnecting, subscribes to ``topics`` at every connect and
    queues what arrives; ``connected`` tells whether the broker is there now."""

    def __init__(
        self,
        client_id: str,
        tls: Tls,
        topics: list[str],
        *,
        will: Will | None = None,
        on_connect_publish: list[tuple[str, bytes]] | None = None,
    ) -> None:
        self.incoming: queue.Queue[Incoming] = queue.Queue(maxsize=10_000)
        self.connected = False
        self.subscribed = threading.Event()
        """Set once the broker granted this connection's subscriptions (or it has none)."""
        self.last_error = "not connected yet"
        self._topics = topics
        self._announce = on_connect_publish or []
        client = mqtt.Client(
            CallbackAPIVersion.VERSION2,
            client_id=client_id,
            clean_session=True,
            protocol=mqtt.MQTTv311,
        )
        client.tls_set(
            ca_certs=str(tls.cafile),
            certfile=str(tls.certfile),
            keyfile=str(tls.keyfile),
            cert_reqs=ssl.CERT_REQUIRED,
            tls_version=ssl.PROTOCOL_TLS_CLIENT,
        )
        client.reconnect_delay_set(min_delay=1, max_delay=5)
        if will is not None:
            client.will_set(will.topic, will.payload, qos=1, retain=True)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        client.on_subscribe = self._on_subscribe
        self.client = client

    def start(self, host: str, port: int, keepalive: int = 5) -> None:
        """Connect in the background (a broker that is away is retried, 1 s to 5 s apart)."""
        self.client.connect_async(host, port, keepalive=keepalive)
        self.client.loop_start()

    def stop(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()

    def publish(self, topic: str, payload: bytes, *, retain: bool = False) -> bool:
        """Queue a QoS 1 message; ``False`` when paho refused it at once (no connection)."""
        info = self.client.publish(topic, payload, qos=1, retain=retain)
        return info.rc == mqtt.MQTT_ERR_SUCCESS

    def _on_connect(
        self,
        client: mqtt.Client,
        userdata: object,
        flags: mqtt.ConnectFlags,
        reason: ReasonCode,
        properties: Properties | None,
    ) -> None:
        if reason.is_failure:
            self.connected = False
            self.last_error = f"broker refused the connection: {reason}"
            return
        self.connected = True
        self.last_error = ""
        # A stop and its answer are small writes: without TCP_NODELAY, Nagle's algorithm
        # holds one back for the peer's delayed ACK (40 ms on Linux), on every hop.
        sock = client.socket()
        if isinstance(sock, socket.socket):  # an ssl.SSLSocket is one
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if self._topics:
            client.subscribe([(t, 1) for t in self._topics])
        else:
            self.subscribed.set()
        for topic, payload in self._announce:
            client.publish(topic, payload, qos=1, retain=True)

    def _on_disconnect(
        self,
        client: mqtt.Client,
        userdata: object,
        flags: mqtt.DisconnectFlags,
        reason: ReasonCode,
        properties: Properties | None,
    ) -> None:
        self.connected = False
        self.subscribed.clear()
        self.last_error = f"disconnected: {reason}"

    def _on_subscribe(
        self,
        client: mqtt.Client,
        userdata: object,
        mid: int,
        reasons: list[ReasonCode],
        properties: Properties | None,
    ) -> None:
        # MQTT 3.1.1's SUBACK grants or refuses each topic (0x80); mosquitto grants a topic
        # its ACL denies and then delivers nothing on it (SR-13.13: the ACL is the rule).
        self.subscribed.set()

    def _on_message(self, client: mqtt.Client, userdata: object, msg: mqtt.MQTTMessage) -> None:
        item = Incoming(msg.topic, bytes(msg.payload), bool(msg.retain), time.monotonic())
        try:
            self.incoming.put_nowait(item)
        except queue.Full:  # never expected: the agent reads as fast as the daemon answers
            self.last_error = "incoming queue full: a message was dropped"

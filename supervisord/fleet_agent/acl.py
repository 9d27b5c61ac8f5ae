"""The broker's access rules for a fleet's stop (SR-13.13): mosquitto's ``acl_file``.

With ``require_certificate true`` and ``use_identity_as_username true`` a client's user name
is its certificate's CN, which the fleet's CA signed: a robot's name, or a console's. The file
gives, per name and nothing by pattern:

- a robot: **read** its stops (``stop/all``, ``stop/group/G`` for its groups,
  ``stop/robot/NAME``), **write** its own acknowledgements and presence; nothing else, so it
  can neither send a stop nor answer for another robot, nor read another robot's stops;
  and read every console's keepalive;
- a console: **write** stops and its own keepalive, **read** every acknowledgement and
  presence.

Mosquitto denies whatever the file does not grant (a refused publish is dropped, a refused
subscription gets no messages). A name that is both a robot and a console is refused here:
one certificate must not be both. Pure: the text, from the roster.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from supervisord.fleet_agent.topics import (
    ALL,
    PREFIX,
    Target,
    ack_topic,
    checked_name,
    keepalive_topic,
    presence_topic,
    stop_topic,
)


def acl_text(fleet: str, robots: Mapping[str, frozenset[str]], consoles: Sequence[str]) -> str:
    """The ``acl_file`` for ``robots`` (name -> groups) and ``consoles``; ``ValueError`` for a
    name that is no plain word or is both a robot and a console."""
    checked_name(fleet, "fleet")
    both = set(robots) & set(consoles)
    if both:
        raise ValueError(f"a robot and a console by one name: {', '.join(sorted(both))}")
    lines = [f"# srcs fleet {fleet}: written by srcsctl fleet acl (docs/fleet.md)", ""]
    for robot, groups in sorted(robots.items()):
        checked_name(robot, "robot")
        lines.append(f"user {robot}")
        lines.append(f"topic read {stop_topic(fleet, ALL)}")
        for group in sorted(groups):
            lines.append(
                f"topic read {stop_topic(fleet, Target('group', checked_name(group, 'group')))}"
            )
        lines.append(f"topic read {stop_topic(fleet, Target('robot', robot))}")
        lines.append(f"topic read {keepalive_topic(fleet, '+')}")
        lines.append(f"topic write {ack_topic(fleet, robot)}")
        lines.append(f"topic write {presence_topic(fleet, robot)}")
        lines.append("")
    for console in sorted(consoles):
        checked_name(console, "console")
        lines.append(f"user {console}")
        lines.append(f"topic write {PREFIX}/{fleet}/stop/#")
        lines.append(f"topic write {keepalive_topic(fleet, console)}")
        lines.append(f"topic read {PREFIX}/{fleet}/ack/+")
        lines.append(f"topic read {PREFIX}/{fleet}/robot/+")
        lines.append("")
    return "\n".join(lines)


def broker_conf(port: int, pki: str, acl_file: str, bind: str = "") -> str:
    """A mosquitto listener for the fleet: TLS with client certificates required, the CN as
    the user name, no anonymous client, and the ACL file (``pki``: the directory holding
    ``ca.pem``, ``broker.pem`` and ``broker.key``)."""
    listener = f"listener {port} {bind}".rstrip()
    return "\n".join(
        [
            "per_listener_settings true",
            listener,
            f"cafile {pki}/ca.pem",
            f"certfile {pki}/broker.pem",
            f"keyfile {pki}/broker.key",
            "tls_version tlsv1.2",
            "require_certificate true",
            "use_identity_as_username true",
            "allow_anonymous false",
            f"acl_file {acl_file}",
            # Small messages go out at once, not after the client's delayed ACK (40 ms).
            "set_tcp_nodelay true",
            "",
        ]
    )

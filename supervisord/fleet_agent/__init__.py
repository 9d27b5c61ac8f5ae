"""The fleet stop's per-robot agent, ``srcs-fleet-agent``, and the pure parts the fleet's
console shares with it (docs/fleet.md "The fleet stop").

``srcsd`` keeps no IP access; this agent, its own unit and user, carries the fleet's messages
between an MQTT broker and the supervisor's client API: a stop from the console becomes a
``fleet_stop`` request, and the daemon's reply becomes the acknowledgement. One job per file:
:mod:`.topics` (the topic names), :mod:`.message` (a stop's payload), :mod:`.replay` (the
replay window), :mod:`.ack` (the acknowledgement), :mod:`.daemon_link` (the API request),
:mod:`.mqtt_edge` (the only module that imports the MQTT client), :mod:`.agent` (the loop).
"""

"""``srcs-sim``: a simulated VSC with its remote, for testing robot code without hardware.

``model`` (the state machine) and ``faults`` (the fault plan) are pure: no I/O, no clock;
time comes in as monotonic seconds. ``serial_side``, ``can_side`` and ``control`` are the
I/O edges (``pty`` the pseudo-terminal serial port); ``engine`` joins them;
``supervisord.cli.sim`` is the command. ``process`` runs the simulator as a child of another
program (``srcsctl demo``, tests) and speaks its control socket.
``docs/simulator.md`` describes it for users.
"""

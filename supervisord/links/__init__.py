"""Links to the VSC: serial (HRI packets), CAN (J1939) and USB HID, one class each.

A link owns one port or bus. The daemon's loop waits on ``fileno()`` and calls ``receive``
when it is readable; ``send`` writes at once. A link never retries by itself: when the world
breaks it, it raises ``LinkBrokenError`` and the loop closes it and reopens it later with
``Backoff``. No link starts a thread.
"""

"""The long-running service: one loop that owns the link, the outputs, the client socket and
the safety core (``srcsd``)."""

"""SRCS safety supervisor: protocol codecs, safety core, daemon, simulator and tools."""

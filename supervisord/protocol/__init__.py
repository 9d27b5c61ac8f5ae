"""The SRCS protocol as pure codecs: bytes and frames in, typed values out, and back.

No module of this package opens a file or port, reads a clock, sleeps or starts a thread
(``tests/protocol/test_purity.py`` proves it).
"""

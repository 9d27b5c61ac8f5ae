"""The simulator's control socket: JSON lines on a Unix stream socket, one request, one reply.

Non-blocking, served from the simulator's one loop: ``read_fds``/``write_fds`` for its
``select``, ``serve`` with the ready descriptors. Replies are queued per client and written
as the client reads them, so a slow client never stalls the simulated VSC. A line that is
not a JSON object gets an error reply; a line longer than ``MAX_LINE`` gets one and the
connection is closed. ``docs/simulator.md`` describes the requests.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any

MAX_LINE = 1 << 20
MAX_CLIENTS = 32
Handler = Callable[[object], dict[str, Any]]


class _Client:
    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.inbox = bytearray()
        self.outbox = bytearray()
        self.closing = False


class ControlServer:
    """Listens at ``path`` (a stale socket file there is replaced; any other file is not)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        with contextlib.suppress(FileNotFoundError):
            if not stat.S_ISSOCK(path.lstat().st_mode):
                raise FileExistsError(f"{path} exists and is not a socket")
            path.unlink()
        self._listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._listener.bind(str(path))
        os.chmod(path, 0o600)  # the simulator's owner only: it can e-stop and unplug
        self._listener.listen(8)
        self._listener.setblocking(False)
        self._clients: dict[int, _Client] = {}

    def read_fds(self) -> list[int]:
        return [self._listener.fileno(), *self._clients]

    def write_fds(self) -> list[int]:
        return [fd for fd, client in self._clients.items() if client.outbox]

    def serve(self, readable: set[int], writable: set[int], handler: Handler) -> None:
        if self._listener.fileno() in readable:
            self._accept()
        for fd, client in list(self._clients.items()):
            if fd in readable:
                self._read(client, handler)
            if client.outbox and (fd in writable or fd in readable):
                self._write(client)
            if client.closing and not client.outbox:
                self._drop(fd)

    def _accept(self) -> None:
        while True:
            try:
                sock, _ = self._listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            if len(self._clients) >= MAX_CLIENTS:
                sock.close()
                continue
            sock.setblocking(False)
            self._clients[sock.fileno()] = _Client(sock)

    def _read(self, client: _Client, handler: Handler) -> None:
        try:
            data = client.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            client.closing = True
            return
        client.inbox += data
        while not client.closing:
            end = client.inbox.find(b"\n")
            if end < 0:
                if len(client.inbox) > MAX_LINE:
                    self._reply(client, {"ok": False, "error": "request line too long"})
                    client.closing = True
                return
            line = bytes(client.inbox[:end]).strip()
            del client.inbox[: end + 1]
            if line:
                self._reply(client, _answer(line, handler))

    def _reply(self, client: _Client, reply: dict[str, Any]) -> None:
        client.outbox += json.dumps(reply).encode() + b"\n"

    def _write(self, client: _Client) -> None:
        try:
            sent = client.sock.send(client.outbox)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            client.outbox.clear()
            client.closing = True
            return
        del client.outbox[:sent]

    def _drop(self, fd: int) -> None:
        client = self._clients.pop(fd)
        client.sock.close()

    def close(self) -> None:
        for fd in list(self._clients):
            self._drop(fd)
        self._listener.close()
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()


def _answer(line: bytes, handler: Handler) -> dict[str, Any]:
    try:
        request = json.loads(line)
    except (ValueError, RecursionError) as error:  # RecursionError: nested thousands deep
        return {"ok": False, "error": f"not JSON: {error}"}
    try:
        return handler(request)
    except Exception as error:
        return {"ok": False, "error": f"internal error: {type(error).__name__}: {error}"}

"""Loopback TCP plumbing shared by the AADM controller and the towers.

The challenge's messages carry no terminator (``snr_dd``, a bare tower id, a telemetry line):
a receiver decides from the bytes so far whether a message is whole (:data:`Verdict`). Every
message has a deadline on the whole message (not per byte), and each server caps the
connections it serves at once (a connection past the cap is closed at once).
"""

from __future__ import annotations

import logging
import socket
import socketserver
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

from skymule.errors import SkymuleError

log = logging.getLogger("skymule.aadm.net")

#: Seconds a whole message may take to arrive.
MESSAGE_DEADLINE_S = 10.0
#: A message that may go on (a telemetry line, a tower id that could have more digits) is
#: whole once the sender is quiet this long [s].
QUIET_S = 0.05
#: Connections a server handles at once; more are closed on arrival. Room for a few dozen
#: slow clients beside the UAV (each is dropped at the message deadline).
MAX_CONNECTIONS = 64
#: The most bytes one message may have.
MESSAGE_LIMIT = 1024

Verdict = Literal["whole", "more", "maybe"]
"""What the bytes so far are: a whole message, a part, or whole unless more comes soon."""


def receive(
    sock: socket.socket,
    verdict: Callable[[bytes], Verdict],
    deadline_s: float | None = None,
) -> bytes | None:
    """One message (None: the peer closed before sending anything).

    Raises TimeoutError when the message is not whole within ``deadline_s`` (default
    :data:`MESSAGE_DEADLINE_S`).
    """
    deadline_s = MESSAGE_DEADLINE_S if deadline_s is None else deadline_s
    end = time.monotonic() + deadline_s
    data = b""
    while True:
        left = end - time.monotonic()
        if left <= 0:
            raise TimeoutError(f"message not whole after {deadline_s:g} s: {data[:40]!r}")
        state = verdict(data) if data else "more"
        sock.settimeout(min(left, QUIET_S) if state == "maybe" else left)
        try:
            chunk = sock.recv(MESSAGE_LIMIT)
        except TimeoutError:
            if state == "maybe":
                return data
            raise
        if not chunk:
            return data or None
        data += chunk
        if len(data) >= MESSAGE_LIMIT or verdict(data) == "whole":
            return data


def receive_all(sock: socket.socket, deadline_s: float = MESSAGE_DEADLINE_S) -> bytes:
    """Everything until the peer closes (a reply followed by the end of the connection)."""
    end = time.monotonic() + deadline_s
    data = b""
    while len(data) < 64 * MESSAGE_LIMIT:
        left = end - time.monotonic()
        if left <= 0:
            raise TimeoutError(f"no end of reply after {deadline_s:g} s")
        sock.settimeout(left)
        chunk = sock.recv(MESSAGE_LIMIT)
        if not chunk:
            break
        data += chunk
    return data


def text_line(data: bytes) -> Verdict:
    """A message whole at a newline, or once the sender is quiet."""
    return "whole" if data.endswith(b"\n") else "maybe"


class CappedServer(socketserver.ThreadingTCPServer):
    """A thread a connection, at most ``MAX_CONNECTIONS`` at once."""

    daemon_threads = True
    allow_reuse_address = True
    request_queue_size = 128  # a burst of connections waits for accept instead of SYN retries

    def __init__(
        self,
        address: tuple[str, int],
        handle: Callable[[socket.socket, str], None],
        max_connections: int | None = None,
    ) -> None:
        self.handle_connection = handle
        max_connections = MAX_CONNECTIONS if max_connections is None else max_connections
        self.max_connections = max_connections
        self._slots = threading.BoundedSemaphore(max_connections)
        self.refused = 0
        super().__init__(address, _Handler)

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self._slots.acquire(blocking=False):
            self.refused += 1
            log.warning(
                "connection from %s refused: %d already open",
                client_address[0],
                self.max_connections,
            )
            self.shutdown_request(request)
            return
        super().process_request(request, client_address)

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()


class _Handler(socketserver.BaseRequestHandler):
    server: CappedServer

    def handle(self) -> None:
        try:
            self.server.handle_connection(self.request, str(self.client_address[0]))
        except (OSError, TimeoutError) as exc:
            log.info("connection from %s dropped: %s", self.client_address[0], exc)


@dataclass(frozen=True)
class Listening:
    """A server serving in a background thread: its address."""

    host: str
    port: int


@contextmanager
def serving(
    host: str,
    port: int,
    handle: Callable[[socket.socket, str], None],
    name: str,
    what: str,
) -> Iterator[Listening]:
    """Serve ``handle`` on ``host:port`` (0: any free port) until the block ends; the server
    and its thread are closed on exit, also on an exception. ``what`` names the option."""
    try:
        server = CappedServer((host, port), handle)
    except OSError as exc:
        raise SkymuleError(f"{what} {port}: cannot listen on {host} ({exc.strerror})") from None
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), name=name, daemon=True)
    thread.start()
    try:
        yield Listening(host, int(server.server_address[1]))
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=10)


def exchange(host: str, port: int, message: str, timeout_s: float = MESSAGE_DEADLINE_S) -> str:
    """Send one message on a new connection and return the whole reply (until close)."""
    with socket.create_connection((host, port), timeout=timeout_s) as sock:
        sock.sendall(message.encode())
        return receive_all(sock, timeout_s).decode("utf-8", "replace")

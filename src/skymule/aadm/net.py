"""Loopback TCP plumbing shared by the AADM controller and the towers.

The challenge's messages carry no terminator (``snr_dd``, a bare tower id, a telemetry line):
a receiver decides from the bytes so far whether a message is whole (:data:`Verdict`). Every
message has a deadline on the whole message (not per byte), and each server caps the
connections it serves at once, in all and per client address (a connection past either cap
is closed at once). A connection that sends nothing within :data:`FIRST_BYTE_S` is closed, so
that a crowd of idle connections cannot hold the slots; refused connections are logged at most
once a second (:class:`RateLimitedLog`).
"""

from __future__ import annotations

import logging
import math
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
#: Seconds a new connection may wait before its first byte (the challenge's clients send their
#: first message at once: ``snr_dd``, a telemetry line, a tower id).
FIRST_BYTE_S = 2.0
#: A message that may go on (a telemetry line, a tower id that could have more digits) is
#: whole once the sender is quiet this long [s].
QUIET_S = 0.05
#: Connections a server handles at once; more are closed on arrival. Room for a few dozen
#: slow clients beside the UAV (each is dropped at the message deadline).
MAX_CONNECTIONS = 64
#: Connections one client address may hold at once on one server (the UAV holds one).
MAX_PER_ADDRESS = 8
#: The most bytes one message may have.
MESSAGE_LIMIT = 1024

Verdict = Literal["whole", "more", "maybe"]
"""What the bytes so far are: a whole message, a part, or whole unless more comes soon."""


def receive(
    sock: socket.socket,
    verdict: Callable[[bytes], Verdict],
    deadline_s: float | None = None,
    first_byte_s: float | None = None,
) -> bytes | None:
    """One message (None: the peer closed before sending anything).

    Raises TimeoutError when the message is not whole within ``deadline_s`` (default
    :data:`MESSAGE_DEADLINE_S`), or when its first byte has not come within ``first_byte_s``
    (None: no such deadline).
    """
    deadline_s = MESSAGE_DEADLINE_S if deadline_s is None else deadline_s
    start = time.monotonic()
    end = start + deadline_s
    data = b""
    while True:
        left = end - time.monotonic()
        if not data and first_byte_s is not None:
            left = min(left, start + first_byte_s - time.monotonic())
            if left <= 0:
                raise TimeoutError(f"nothing sent within {first_byte_s:g} s")
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


class RateLimitedLog:
    """A warning at most once every ``every_s`` seconds; the ones held back are counted in the
    next line (a crowd of refused connections costs one line a second, not one each)."""

    def __init__(
        self, logger: logging.Logger, every_s: float = 1.0, level: int = logging.WARNING
    ) -> None:
        self.logger = logger
        self.every_s = every_s
        self.level = level
        self._next = -math.inf
        self._held = 0
        self._lock = threading.Lock()

    def warning(self, message: str) -> bool:
        """Log ``message`` unless one went out less than ``every_s`` ago; True if logged."""
        with self._lock:
            now = time.monotonic()
            if now < self._next:
                self._held += 1
                return False
            held, self._held = self._held, 0
            self._next = now + self.every_s
        more = f" (and {held} more like it in the last {self.every_s:g} s)" if held else ""
        self.logger.log(self.level, "%s%s", message, more)
        return True


class CappedServer(socketserver.ThreadingTCPServer):
    """A thread a connection, at most ``MAX_CONNECTIONS`` at once and ``MAX_PER_ADDRESS``
    from one client address."""

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
        self.max_per_address = MAX_PER_ADDRESS
        self._slots = threading.BoundedSemaphore(max_connections)
        self._per_address: dict[str, int] = {}
        self._count_lock = threading.Lock()
        self.refused = 0
        self.refusals = RateLimitedLog(log)
        self.drops = RateLimitedLog(log, level=logging.INFO)
        super().__init__(address, _Handler)

    def process_request(self, request: Any, client_address: Any) -> None:
        peer = str(client_address[0])
        with self._count_lock:
            crowded = self._per_address.get(peer, 0) >= self.max_per_address
            if not crowded and not self._slots.acquire(blocking=False):
                why = f"{self.max_connections} connections already open"
            elif crowded:
                why = f"{self.max_per_address} already open from this address"
            else:
                why = ""
                self._per_address[peer] = self._per_address.get(peer, 0) + 1
            if why:
                self.refused += 1
        if why:
            self.refusals.warning(f"connection from {peer} refused: {why}")
            self.shutdown_request(request)
            return
        super().process_request(request, client_address)

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            peer = str(client_address[0])
            with self._count_lock:
                left = self._per_address.get(peer, 1) - 1
                if left > 0:
                    self._per_address[peer] = left
                else:
                    self._per_address.pop(peer, None)
            self._slots.release()


class _Handler(socketserver.BaseRequestHandler):
    server: CappedServer

    def handle(self) -> None:
        try:
            self.server.handle_connection(self.request, str(self.client_address[0]))
        except (OSError, TimeoutError) as exc:
            self.server.drops.warning(f"connection from {self.client_address[0]} dropped: {exc}")


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

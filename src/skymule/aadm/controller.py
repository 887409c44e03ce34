"""An emulator of the AADM challenge controller: a loopback TCP server with its accounting.

The challenge's controller has no radio model; this one takes the SNR from any skymule signal
source at the UAV's current position (a propagation model or a fitted radio map, through the
scenario's :class:`~skymule.world.Mission`), or replays a recorded trace one sample a poll.

Accounting (issue "AADM for real"; :mod:`skymule.aadm.score`), per poll:

* the volumes are shared at the first poll with the UAV above 24 m; t1 starts there;
* when the UAV names a tower, the tower's SNR *of this poll* goes through the AADM CQI table
  x 1.4 MHz x ``poll_s`` (the nominal 1 s) and is added to the tower's total, clipped to its
  volume (:func:`~skymule.aadm.score.poll_download_bit`);
* the clock is the poll count: poll k after sharing stands for [k, k+1) x ``poll_s`` of t1,
  however fast the UAV polls, so that nothing drifts with wall time (a 10-Hz test run is the
  same mission as a 1-Hz flight); t1 at completion is (k+1) x ``poll_s``;
* serving stops when poll k starts at or after the window (k x poll_s >= 500 s), once
  everything is downloaded, or when the UAV reports itself disarmed.

One row a served poll goes to the download log (:class:`~skymule.aadm.files.DownloadLogWriter`)
with the emulated time (sharing time + k x poll_s). Bad requests get an ``error:`` line and
a log message; a client that disconnects mid-poll costs nothing (the poll is not counted).
"""

from __future__ import annotations

import logging
import socket
import socketserver
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

from skymule.aadm import protocol
from skymule.aadm.files import DownloadLogWriter, parse_tower_id
from skymule.aadm.score import (
    AADM_POLL_S,
    AADM_WINDOW_S,
    SHARE_ALTITUDE_M,
    aadm_score_one,
    poll_download_bit,
)
from skymule.errors import SkymuleError
from skymule.units import BITS_PER_MBIT
from skymule.world import Mission

log = logging.getLogger("skymule.aadm.controller")

#: Seconds a connection may stay silent before the poll is dropped.
READ_TIMEOUT_S = 10.0

PositionSource = Callable[[], tuple[np.ndarray, bool]]
"""In-process UAV state: () -> (position (3,) [m], armed)."""


@dataclass(frozen=True)
class PollSnapshot:
    """What the controller told the UAV in one poll (accounting uses this SNR)."""

    snr_db: np.ndarray
    serving: bool


class SignalFeed:
    """SNR per poll: the mission's source at the UAV's position, or a trace sample a poll."""

    def __init__(self, mission: Mission) -> None:
        self.mission = mission
        self.home_m = np.zeros(3)

    def snr_db(self, position_m: np.ndarray | None, poll: int) -> tuple[np.ndarray, np.ndarray]:
        """(SNR (N,) [dB], position (3,) [m]) for a poll; the trace replays sample ``poll``."""
        mission = self.mission
        if mission.source is not None:
            where = self.home_m if position_m is None else position_m
            return mission.source.snr_db(where[None])[0], where
        assert mission.track is not None
        sample = min(poll, mission.track.n_samples - 1)
        return mission.track.snr_db[sample], mission.track.position_m[sample]


class ControllerCore:
    """The controller's state machine, without sockets (thread-safe)."""

    def __init__(
        self,
        mission: Mission,
        volumes_mbit: np.ndarray | None = None,
        *,
        poll_s: float = AADM_POLL_S,
        window_s: float = AADM_WINDOW_S,
        log_path: Path | None = None,
        position_source: PositionSource | None = None,
    ) -> None:
        volumes = mission.buffers_bit / BITS_PER_MBIT if volumes_mbit is None else volumes_mbit
        if len(volumes) != mission.n_sensors:
            raise SkymuleError(
                f"volumes: {len(volumes)} values for the scenario's {mission.n_sensors} towers"
            )
        self.n_towers = mission.n_sensors
        self.volumes_bit = np.asarray(volumes, float) * BITS_PER_MBIT
        self.received_bit = np.zeros(self.n_towers)
        self.poll_s = poll_s
        self.window_s = window_s
        self.feed = SignalFeed(mission)
        self.position_source = position_source
        self._log_path = log_path
        self._writer: DownloadLogWriter | None = None
        self._lock = threading.Lock()
        self._requests = 0  # snr_dd requests seen (trace replay index)
        self._last_position: np.ndarray | None = None
        self.shared_at: datetime | None = None
        self.served_polls = 0  # polls counted since sharing (the clock of t1)
        self.per_poll_bit: list[float] = []
        self.stopped: str | None = None  # why serving stopped
        self.disarmed = False  # the UAV reported itself disarmed after sharing (session over)
        self.errors = 0

    # -- one poll ---------------------------------------------------------------------------

    def request(self, line: str) -> tuple[str, PollSnapshot | None]:
        """Answer one ``snr_dd`` line: (reply line, snapshot for the tower choice)."""
        try:
            parsed = protocol.parse_request(line)
        except SkymuleError as exc:
            return self._error(str(exc)), None
        with self._lock:
            position, armed = parsed.position_m, parsed.armed
            if self.position_source is not None and position is None:
                position, armed = self.position_source()
            if position is not None:
                self._last_position = position
            snr, where = self.feed.snr_db(self._last_position, self._requests)
            self._requests += 1
            if armed is False and self.shared_at is not None:
                self.disarmed = True
                self.stopped = self.stopped or "disarmed"
            known = position is not None or self.feed.mission.source is None
            if self.shared_at is None and not (known and where[2] > SHARE_ALTITUDE_M):
                why = f"wait:UAV below {SHARE_ALTITUDE_M:g} m, cannot share the volumes yet"
                return f"{why};{protocol.format_snr(snr)}", PollSnapshot(snr, False)
            if self.shared_at is None:
                self.shared_at = datetime.now()
                self._open_log()
                head = "vol:" + protocol.format_values(self.volumes_bit / BITS_PER_MBIT)
            elif self._complete():
                head = "download_complete:1"
            else:
                head = "download:" + protocol.format_values(self.received_bit / BITS_PER_MBIT)
            return f"{head};{protocol.format_snr(snr)}", PollSnapshot(snr, self._serving())

    def choose(self, line: str, snapshot: PollSnapshot) -> str:
        """Account the tower the UAV named for the poll ``snapshot`` came from."""
        try:
            tower = parse_tower_id(line, self.n_towers, "tower choice")
        except SkymuleError as exc:
            return self._error(str(exc))
        with self._lock:
            if not snapshot.serving or not self._serving():
                reason = self.stopped or (
                    "volumes not shared yet" if self.shared_at is None else "not serving"
                )
                return f"report:tower {tower} not served ({reason})"
            index = tower - 1
            left = self.volumes_bit[index] - self.received_bit[index]
            bits = float(
                poll_download_bit(snapshot.snr_db[index], left, self.poll_s)
            )  # the SNR this poll reported, as the controller does
            self.received_bit[index] += bits
            self.per_poll_bit.append(bits)
            self.served_polls += 1
            self._write_row()
            if self._complete():
                self.stopped = "all data downloaded"
            elif self.served_polls * self.poll_s >= self.window_s - 1e-9:
                self.stopped = f"window of {self.window_s:g} s closed"
            total = self.received_bit.sum() / BITS_PER_MBIT
            return (
                f"report:tower {tower} +{bits / BITS_PER_MBIT:.3f} Mbit; total {total:.3f}/"
                f"{self.volumes_bit.sum() / BITS_PER_MBIT:.3f} Mbit; "
                f"t1 {self.served_polls * self.poll_s:g} s"
            )

    def stop(self, reason: str) -> None:
        with self._lock:
            self.stopped = self.stopped or reason

    def close(self) -> None:
        with self._lock:
            if self._writer is not None:
                self._writer.close()
                self._writer = None

    # -- results ----------------------------------------------------------------------------

    def score(self) -> dict[str, float | bool]:
        """The score parts of the session so far (the rule in force)."""
        with self._lock:
            per_poll = np.asarray(self.per_poll_bit, float)
            total = float(self.volumes_bit.sum())
        return aadm_score_one(per_poll, total, self.poll_s, self.window_s)

    def received_mbit(self) -> np.ndarray:
        with self._lock:
            return self.received_bit / BITS_PER_MBIT

    # -- internals (called with the lock held) ---------------------------------------------

    def _complete(self) -> bool:
        return bool(np.all(self.received_bit >= self.volumes_bit * (1 - 1e-9)))

    def _serving(self) -> bool:
        return self.shared_at is not None and self.stopped is None

    def _error(self, message: str) -> str:
        with self._lock:
            self.errors += 1
        log.warning("bad input from the UAV: %s", message)
        return f"error:{message}"

    def _open_log(self) -> None:
        if self._log_path is not None and self._writer is None:
            self._writer = DownloadLogWriter(self._log_path, self.n_towers)

    def _write_row(self) -> None:
        if self._writer is not None and self.shared_at is not None:
            when = self.shared_at + timedelta(seconds=(self.served_polls - 1) * self.poll_s)
            self._writer.write(when, self.received_bit / BITS_PER_MBIT)


# ---------------------------------------------------------------------------
# TCP
# ---------------------------------------------------------------------------


def _read_line(stream: socket.socket, limit: int = 4096) -> str | None:
    """One ``\\n``-terminated line (None on disconnect); at most ``limit`` bytes."""
    data = bytearray()
    while not data.endswith(b"\n"):
        chunk = stream.recv(1)
        if not chunk:
            return None if not data else data.decode("utf-8", "replace")
        data += chunk
        if len(data) > limit:
            return data.decode("utf-8", "replace")
    return data.decode("utf-8", "replace")


class _PollHandler(socketserver.BaseRequestHandler):
    server: _ControllerServer

    def handle(self) -> None:
        core = self.server.core
        sock = self.request
        sock.settimeout(READ_TIMEOUT_S)
        try:
            line = _read_line(sock)
            if line is None:
                return
            reply, snapshot = core.request(line)
            sock.sendall((reply + "\n").encode())
            if snapshot is None:
                return
            choice = _read_line(sock)
            if choice is None:
                log.info("UAV disconnected before naming a tower; poll not counted")
                return
            sock.sendall((core.choose(choice, snapshot) + "\n").encode())
        except (OSError, TimeoutError) as exc:
            log.info("poll dropped: %s", exc)


class _ControllerServer(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address: tuple[str, int], core: ControllerCore) -> None:
        self.core = core
        super().__init__(address, _PollHandler)


@dataclass(frozen=True)
class RunningController:
    """A controller serving in a background thread."""

    core: ControllerCore
    host: str
    port: int


@contextmanager
def serve_controller(
    core: ControllerCore, host: str = "127.0.0.1", port: int = 0
) -> Iterator[RunningController]:
    """Serve ``core`` on ``host:port`` (0: any free port) until the block ends.

    The server, its thread and the download log are closed on exit, also on an exception.
    """
    try:
        server = _ControllerServer((host, port), core)
    except OSError as exc:
        raise SkymuleError(f"--port {port}: cannot listen on {host} ({exc.strerror})") from None
    thread = threading.Thread(
        target=server.serve_forever, args=(0.05,), name="aadm-controller", daemon=True
    )
    thread.start()
    try:
        yield RunningController(core, host, int(server.server_address[1]))
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=10)
        core.close()


def poll_once(
    host: str,
    port: int,
    choose: Callable[[protocol.Reply], int],
    position_m: np.ndarray | None = None,
    armed: bool | None = None,
    timeout_s: float = READ_TIMEOUT_S,
) -> tuple[protocol.Reply, str]:
    """One poll as a comm process makes it: (controller reply, report line).

    ``choose`` maps the reply to a tower id (1..N). A reply of kind ``error`` is returned
    with an empty report.
    """
    with socket.create_connection((host, port), timeout=timeout_s) as sock:
        sock.sendall((protocol.format_request(position_m, armed) + "\n").encode())
        line = _read_line(sock)
        if line is None:
            raise SkymuleError(f"controller {host}:{port} closed the connection without a reply")
        reply = protocol.parse_reply(line)
        if reply.kind == "error":
            return reply, ""
        sock.sendall(f"{choose(reply)}\n".encode())
        report = _read_line(sock)
        return reply, (report or "").strip()

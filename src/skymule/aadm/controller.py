"""An emulator of the AADM challenge controller, speaking its bytes (:mod:`~skymule.aadm.protocol`).

Two loopback TCP servers share one :class:`ControllerCore`: the UAV's polls (``snr_dd``, then
the tower id) and the telemetry (``alt:..,arm:..,lat:..,lon:..``), from which the controller
learns where the UAV is and whether it is armed, as on the testbed. The challenge's controller
has no radio model: it asks the four towers; this one takes the SNR from any skymule signal
source at the UAV's position (a propagation model or a fitted radio map, through the
scenario's :class:`~skymule.world.Mission`), or replays a recorded trace one sample a poll.

Accounting (:mod:`skymule.aadm.score`), per poll:

* the volumes are shared at the first poll with the UAV above 24 m; t1 starts there;
* when the UAV names a tower, the tower's SNR *of this poll* goes through the AADM CQI table
  x 1.4 MHz x ``poll_s`` (the nominal 1 s) and is added to the tower's total, clipped to its
  volume (:func:`~skymule.aadm.score.poll_download_bit`);
* the clock is the poll count: poll k after sharing stands for [k, k+1) x ``poll_s`` of t1,
  however fast the UAV polls (a 10-Hz test run is the same mission as a 1-Hz flight; the
  testbed's controller uses the wall clock); t1 at completion is (k+1) x ``poll_s``;
* serving stops when poll k starts at or after the window (k x poll_s >= 500 s), once
  everything is downloaded, or when the telemetry says the UAV disarmed after sharing (a
  disarmed or landed UAV is not served; the testbed then answers "Cannot share now").

Where this emulator differs from the testbed's controller, on purpose: its SNR is the one at
the UAV's position at this poll (the testbed's controller asks its towers after each poll, so
its SNR is one poll old), a request that is not ``snr_dd`` gets an error instead of a poll,
and a session is bound to its UAV: the address whose poll got the volumes owns the polls, the
first telemetry sender owns the telemetry (others are refused with one line).

One row a served poll goes to the download log (:class:`~skymule.aadm.files.DownloadLogWriter`)
with the emulated time (sharing time + k x poll_s). A client that disconnects mid-poll costs
nothing (the poll is not counted).
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

from skymule.aadm import net, protocol
from skymule.aadm.files import DownloadLogWriter, parse_tower_id
from skymule.aadm.score import (
    AADM_POLL_S,
    AADM_WINDOW_S,
    SHARE_ALTITUDE_M,
    aadm_score_one,
    poll_download_bit,
)
from skymule.errors import SkymuleError
from skymule.geo import LocalFrame
from skymule.rules.contract import window_slots
from skymule.rules.score import COMPLETE_RTOL
from skymule.units import BITS_PER_MBIT
from skymule.world import Mission

log = logging.getLogger("skymule.aadm.controller")

PositionSource = Callable[[], tuple[np.ndarray, bool]]
"""In-process UAV state: () -> (position (3,) [m], armed)."""


@dataclass(frozen=True)
class PollSnapshot:
    """What the controller told the UAV in one poll (accounting uses this SNR)."""

    snr_db: np.ndarray
    serving: bool
    waiting: bool = False  # the reply was "Cannot share now"


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


def telemetry_position(
    message: protocol.Telemetry, frame: LocalFrame, previous: np.ndarray | None
) -> np.ndarray:
    """(3,) the UAV's position [m] in the local frame after one telemetry message (fields it
    did not send keep their previous value; at first, the launch point on the ground)."""
    old = np.zeros(3) if previous is None else previous
    x_m, y_m = float(old[0]), float(old[1])
    if message.lat_deg is not None and message.lon_deg is not None:
        local = frame.to_local(message.lat_deg, message.lon_deg)
        x_m, y_m = float(local[0]), float(local[1])
    z_m = float(old[2]) if message.alt_m is None else message.alt_m
    return np.array([x_m, y_m, z_m])


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
        self.mission = mission
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
        self._position: np.ndarray | None = None  # from telemetry
        self._armed: bool | None = None
        self.shared_at: datetime | None = None
        self.served_polls = 0  # polls counted since sharing (the clock of t1)
        self.per_poll_bit: list[float] = []
        self.stopped: str | None = None  # why serving stopped
        self.disarmed = False  # the UAV disarmed after sharing (session over)
        self.errors = 0
        self.uav_host: str | None = None
        self.telemetry_host: str | None = None
        self.last_poll_at: float | None = None  # monotonic time of the last poll since sharing
        self._complete_told = False
        self._start_told = False
        self._score_told = False

    # -- telemetry ---------------------------------------------------------------------------

    def telemetry(self, text: str, peer: str = "") -> str:
        """Take one telemetry message; the reply the testbed's controller gives."""
        with self._lock:
            if self.telemetry_host is None:
                self.telemetry_host = peer
            elif peer != self.telemetry_host:
                return self._refuse(
                    f"telemetry from {peer}: the session's comes from {self.telemetry_host}",
                    "Error: ",
                )
        try:
            message = protocol.parse_telemetry(text)
        except SkymuleError as exc:
            with self._lock:
                return self._refuse(str(exc), "Error: ")
        with self._lock:
            self._take(message)
            if self.shared_at is None:
                return protocol.NOT_STARTED
            if self.stopped is not None and not self._score_told:
                self._score_told = self._start_told = True  # the score line replaces it
                parts = self._score_locked()
                return protocol.format_score(
                    float(parts["aadm_t1_s"]),
                    float(parts["aadm_s1"]),
                    float(parts["aadm_s2"]),
                    float(parts["aadm_score"]),
                    window_closed=self.stopped.startswith("window"),
                )
            if not self._start_told:
                self._start_told = True
                return f"Download starts at {protocol.stamp(self.shared_at)}"
            return protocol.NOTHING_NEW

    def _take(self, message: protocol.Telemetry) -> None:
        self._position = telemetry_position(message, self.mission.frame, self._position)
        if message.armed is not None:
            self._armed = message.armed
            self._note_arm(message.armed)

    def _note_arm(self, armed: bool) -> None:
        if not armed and self.shared_at is not None:
            self.disarmed = True
            self.stopped = self.stopped or "disarmed"

    # -- one poll ----------------------------------------------------------------------------

    def request(self, text: str, peer: str = "") -> tuple[str, PollSnapshot | None]:
        """Answer one request: (reply, snapshot for the tower choice; None: no choice follows)."""
        with self._lock:
            if text.strip() != protocol.REQUEST:
                return self._refuse(
                    f"request {text.strip()[:40]!r} is not allowed; expected {protocol.REQUEST!r}",
                    f"{protocol.PREFIX} ",
                ), None
            if self.uav_host is not None and peer != self.uav_host:
                return self._refuse(
                    f"poll from {peer}: this session's UAV is at {self.uav_host}",
                    f"{protocol.PREFIX} ",
                ), None
            position, armed = self._position, self._armed
            if self.position_source is not None:
                position, armed = self.position_source()
                self._note_arm(armed)
            snr, where = self.feed.snr_db(position, self._requests)
            self._requests += 1
            known = position is not None or self.feed.mission.source is None
            if self.disarmed or (
                self.shared_at is None and not (known and where[2] > SHARE_ALTITUDE_M)
            ):
                return protocol.WAIT_REPLY, PollSnapshot(snr, False, waiting=True)
            self.last_poll_at = time.monotonic()
            if self.shared_at is None:
                self.shared_at = datetime.now()
                self.uav_host = peer
                self._open_log()
                head = protocol.format_volumes(self.volumes_bit / BITS_PER_MBIT)
            elif self._complete() and not self._complete_told:
                self._complete_told = True
                head = "download_complete:1"
            else:
                head = protocol.format_downloads(self.received_bit / BITS_PER_MBIT)
            return f"{head};{protocol.format_snr(snr)}", PollSnapshot(snr, self._serving())

    def choose(self, text: str, snapshot: PollSnapshot) -> str:
        """Account the tower the UAV named for the poll ``snapshot`` came from."""
        if snapshot.waiting:
            return protocol.WAIT_REPORT
        try:
            tower = parse_tower_id(text, self.n_towers, "tower choice")
        except SkymuleError as exc:
            with self._lock:
                self.errors += 1
            log.warning("bad input from the UAV: %s", exc)
            return protocol.INVALID_TOWER
        index = tower - 1
        with self._lock:
            left = self.volumes_bit[index] - self.received_bit[index]
            serving = snapshot.serving and self._serving()
            when = self._poll_time(self.served_polls if serving else self.served_polls - 1)
            full = left <= self.volumes_bit[index] * COMPLETE_RTOL
            bits = 0.0
            if serving:  # the SNR this poll reported, as the controller does
                bits = float(poll_download_bit(snapshot.snr_db[index], left, self.poll_s))
                self.received_bit[index] += bits
                self.per_poll_bit.append(bits)
                self.served_polls += 1
                self._write_row()
                if self._complete():
                    self.stopped = "all data downloaded"
                elif self.served_polls >= window_slots(self.window_s, self.poll_s):
                    self.stopped = f"window of {self.window_s:g} s closed"
            if full:
                return protocol.format_no_data_left(when, tower)
            return protocol.format_report(
                when,
                tower,
                float(snapshot.snr_db[index]),
                bits / BITS_PER_MBIT / self.poll_s,
                self.received_bit[index] / BITS_PER_MBIT,
            )

    def stop(self, reason: str) -> None:
        with self._lock:
            self.stopped = self.stopped or reason

    def close(self) -> None:
        with self._lock:
            if self._writer is not None:
                self._writer.close()
                self._writer = None

    # -- results -----------------------------------------------------------------------------

    def score(self) -> dict[str, float | bool]:
        """The score parts of the session so far (the rule in force)."""
        with self._lock:
            return self._score_locked()

    def received_mbit(self) -> np.ndarray:
        with self._lock:
            return self.received_bit / BITS_PER_MBIT

    def idle_s(self) -> float | None:
        """Seconds since the last poll of a running session (None: not running)."""
        with self._lock:
            if self.last_poll_at is None or self.stopped is not None:
                return None
            return time.monotonic() - self.last_poll_at

    # -- internals (called with the lock held) -----------------------------------------------

    def _score_locked(self) -> dict[str, float | bool]:
        per_poll = np.asarray(self.per_poll_bit, float)
        return aadm_score_one(per_poll, float(self.volumes_bit.sum()), self.poll_s, self.window_s)

    def _complete(self) -> bool:
        return bool(np.all(self.received_bit >= self.volumes_bit * (1 - 1e-9)))

    def _serving(self) -> bool:
        return self.shared_at is not None and self.stopped is None

    def _refuse(self, message: str, prefix: str) -> str:
        self.errors += 1
        log.warning("refused: %s", message)
        return f"{prefix}{message}"

    def _poll_time(self, poll: int) -> datetime:
        shared = self.shared_at or datetime.now()
        return shared + timedelta(seconds=max(poll, 0) * self.poll_s)

    def _open_log(self) -> None:
        if self._log_path is not None and self._writer is None:
            self._writer = DownloadLogWriter(self._log_path, self.n_towers)

    def _write_row(self) -> None:
        if self._writer is not None:
            self._writer.write(
                self._poll_time(self.served_polls - 1), self.received_bit / BITS_PER_MBIT
            )


# ---------------------------------------------------------------------------
# TCP
# ---------------------------------------------------------------------------


def request_verdict(data: bytes) -> net.Verdict:
    """``snr_dd``, bare or with a newline; anything else is whole as soon as it differs."""
    text = data.decode("utf-8", "replace").strip()
    return "more" if protocol.REQUEST.startswith(text) and text != protocol.REQUEST else "whole"


def tower_verdict(n_towers: int) -> Callable[[bytes], net.Verdict]:
    """A bare tower id is whole once no further digit could make a valid id."""

    def verdict(data: bytes) -> net.Verdict:
        text = data.decode("utf-8", "replace")
        cell = text.strip()
        if not cell:
            return "more"
        if text.endswith("\n") or not cell.isdigit() or int(cell) * 10 > n_towers:
            return "whole"
        return "maybe"

    return verdict


def _serve_poll(core: ControllerCore) -> Callable[[socket.socket, str], None]:
    def handle(sock: socket.socket, peer: str) -> None:
        data = net.receive(sock, request_verdict)
        if data is None:
            return
        reply, snapshot = core.request(data.decode("utf-8", "replace"), peer)
        sock.sendall(reply.encode())
        if snapshot is None:
            return
        choice = net.receive(sock, tower_verdict(core.n_towers))
        if choice is None:
            log.info("UAV disconnected before naming a tower; poll not counted")
            return
        sock.sendall(core.choose(choice.decode("utf-8", "replace"), snapshot).encode())

    return handle


def _serve_telemetry(core: ControllerCore) -> Callable[[socket.socket, str], None]:
    def handle(sock: socket.socket, peer: str) -> None:
        data = net.receive(sock, net.text_line)
        if data is not None:
            sock.sendall(core.telemetry(data.decode("utf-8", "replace"), peer).encode())

    return handle


@dataclass(frozen=True)
class RunningController:
    """A controller serving in background threads (``telemetry_port`` None: no telemetry)."""

    core: ControllerCore
    host: str
    port: int
    telemetry_port: int | None = None


@contextmanager
def serve_controller(
    core: ControllerCore,
    host: str = "127.0.0.1",
    port: int = 0,
    telemetry_port: int | None = 0,
) -> Iterator[RunningController]:
    """Serve ``core`` on ``host:port`` and its telemetry on ``telemetry_port`` (0: any free
    port; None: none) until the block ends; servers, threads and the download log are closed
    on exit, also on an exception."""
    with ExitStack() as stack:
        stack.callback(core.close)
        polls = stack.enter_context(
            net.serving(host, port, _serve_poll(core), "aadm-controller", "--port")
        )
        telemetry: net.Listening | None = None
        if telemetry_port is not None:
            telemetry = stack.enter_context(
                net.serving(
                    host,
                    telemetry_port,
                    _serve_telemetry(core),
                    "aadm-controller",
                    "--telemetry-port",
                )
            )
        yield RunningController(core, host, polls.port, telemetry.port if telemetry else None)


def poll_once(
    host: str,
    port: int,
    choose: Callable[[protocol.Reply], int],
    n_towers: int,
    timeout_s: float = net.MESSAGE_DEADLINE_S,
) -> tuple[protocol.Reply, str]:
    """One poll as the challenge's comm script makes it (bare ``snr_dd``, bare tower id):
    (controller reply, report text). ``choose`` maps the reply to a tower id (1..N); a reply
    of kind ``error`` is returned with an empty report."""
    with socket.create_connection((host, port), timeout=timeout_s) as sock:
        sock.sendall(protocol.REQUEST.encode())
        data = net.receive(
            sock,
            lambda got: "whole" if protocol.reply_complete(got, n_towers) else "maybe",
            timeout_s,
        )
        if data is None:
            raise SkymuleError(f"controller {host}:{port} closed the connection without a reply")
        reply = protocol.parse_reply(data.decode("utf-8", "replace"))
        if reply.kind == "error":
            return reply, ""
        sock.sendall(str(choose(reply)).encode())
        report = net.receive_all(sock, timeout_s).decode("utf-8", "replace").strip()
        if not report:  # the controller always answers the tower id: the link broke
            raise SkymuleError(f"controller {host}:{port} closed the connection without a report")
        return reply, report


def send_telemetry(host: str, port: int, message: str, timeout_s: float = 5.0) -> str:
    """One telemetry message (newline-terminated, which the testbed tolerates); the reply."""
    return net.exchange(host, port, message + "\n", timeout_s).strip()

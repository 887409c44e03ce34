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
  volume (:func:`~skymule.aadm.score.poll_download_bit`).

Two clocks (``clock``):

* ``wall``, the testbed's: t1 is the wall time from sharing to the first telemetry message
  after the download completed, the window closed or the UAV disarmed (the controller learns
  of each only from telemetry, and answers that message with the score line); at most one
  poll is answered a second (:class:`Pacer`); polls are served and credited after 500 s until
  that message; after it, a poll in a new round gets "The system is currently off".
  :class:`WallClock` may run faster than real time for tests;
* ``poll``, for accelerated runs: poll k after sharing stands for [k, k+1) x ``poll_s`` of t1
  however fast the UAV polls (a 10-Hz test run is the same mission as a 1-Hz flight, and the
  flight equals ``skymule run``); t1 at completion is (k+1) x ``poll_s``; serving stops when
  poll k starts at or after the window, once everything is downloaded, or when the telemetry
  says the UAV disarmed after sharing.

Two dialects (``dialect``): ``testbed`` reads each message as one ``recv`` returns it, serves
any request as a poll, takes only a bare digit as a tower id (``1\n`` is ``Invalid BS
Number``: nothing downloaded, the poll still counting) and warns in one line for what would
fail on the testbed; ``lenient`` strips whitespace and refuses requests other than ``snr_dd``.

Where this emulator differs from the testbed's controller, on purpose: its SNR is the one at
the UAV's position at this poll (the testbed's controller asks its towers after each poll, so
its SNR is one poll old); a session is bound to its UAV (the first valid telemetry sender owns
the telemetry and the polls; without telemetry, the address whose poll got the volumes), and
telemetry values are range-checked; after the score it keeps answering (the testbed closes
its telemetry port).

One row a served poll goes to the download log (:class:`~skymule.aadm.files.DownloadLogWriter`)
with the emulated time (sharing time + k x poll_s; on the wall clock the report's time). A
client that disconnects mid-poll costs nothing (the poll is not counted).
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


CLOCKS = ("wall", "poll")
DIALECTS = ("testbed", "lenient")
#: The testbed's controller accepts at most one UAV connection a second: its accept loop
#: sleeps until 1 s after the start of the previous round [s].
ACCEPT_GAP_S = 1.0


class WallClock:
    """Seconds on the testbed's wall clock, run ``speed`` times faster than real time (1: real
    time; more only to keep a test short)."""

    def __init__(self, speed: float = 1.0) -> None:
        if not speed > 0:
            raise SkymuleError(f"clock speed {speed:g}: must be > 0")
        self.speed = speed
        self._origin = time.monotonic()

    def now(self) -> float:
        return (time.monotonic() - self._origin) * self.speed

    def sleep_until(self, when: float) -> None:
        wait = (when - self.now()) / self.speed
        if wait > 0:
            time.sleep(wait)


class Pacer:
    """The testbed's poll loop: round k starts, accepts the next connection, and sleeps until
    :data:`ACCEPT_GAP_S` after its start; so polls are answered at most once a second."""

    def __init__(self, clock: WallClock) -> None:
        self.clock = clock
        self._round_start = clock.now()
        self._lock = threading.Lock()

    def admit(self) -> float:
        """Wait for this poll's turn; returns when its round started [testbed s]."""
        with self._lock:
            round_start = self._round_start
            accept = max(self.clock.now(), round_start)
            self._round_start = max(accept, round_start + ACCEPT_GAP_S)
        self.clock.sleep_until(accept)
        return round_start


class ControllerCore:
    """The controller's state machine, without sockets (thread-safe).

    ``clock``: ``wall`` measures t1 and the window on the wall clock as the testbed's
    controller does (t1 = the first telemetry message after the download completed, or after
    the window closed, minus the time the volumes were shared; polls at most one a second;
    crediting goes on after 500 s until the score is out); ``poll`` counts one poll as
    ``poll_s`` (accelerated runs: poll k stands for [k, k+1) x poll_s, and the flight equals
    ``skymule run``). ``dialect``: ``testbed`` answers as the testbed does (any request is a
    poll; a tower id must be the bare digit, else ``Invalid BS Number`` and nothing is
    downloaded, the poll still counting), with a one-line warning for whatever would fail
    there; ``lenient`` strips whitespace and refuses requests other than ``snr_dd``.
    """

    def __init__(
        self,
        mission: Mission,
        volumes_mbit: np.ndarray | None = None,
        *,
        poll_s: float = AADM_POLL_S,
        window_s: float = AADM_WINDOW_S,
        log_path: Path | None = None,
        position_source: PositionSource | None = None,
        clock: str = "poll",
        dialect: str = "testbed",
        speed: float = 1.0,
    ) -> None:
        volumes = mission.buffers_bit / BITS_PER_MBIT if volumes_mbit is None else volumes_mbit
        if len(volumes) != mission.n_sensors:
            raise SkymuleError(
                f"volumes: {len(volumes)} values for the scenario's {mission.n_sensors} towers"
            )
        if clock not in CLOCKS:
            raise SkymuleError(f"--clock {clock!r} is not allowed; allowed: {', '.join(CLOCKS)}")
        if dialect not in DIALECTS:
            raise SkymuleError(
                f"--dialect {dialect!r} is not allowed; allowed: {', '.join(DIALECTS)}"
            )
        self.mission = mission
        self.n_towers = mission.n_sensors
        self.volumes_bit = np.asarray(volumes, float) * BITS_PER_MBIT
        self.received_bit = np.zeros(self.n_towers)
        self.poll_s = poll_s
        self.window_s = window_s
        self.clock = clock
        self.dialect = dialect
        self.testbed_clock = WallClock(speed)
        self.pacer = Pacer(self.testbed_clock) if clock == "wall" else None
        self.feed = SignalFeed(mission)
        self.position_source = position_source
        self._log_path = log_path
        self._writer: DownloadLogWriter | None = None
        self._lock = threading.Lock()
        self._requests = 0  # requests seen (trace replay index)
        self._position: np.ndarray | None = None  # from telemetry
        self._armed: bool | None = None
        self.shared_at: datetime | None = None
        self.served_polls = 0  # polls counted since sharing (the clock of t1 with clock=poll)
        self.per_poll_bit: list[float] = []
        self.stopped: str | None = None  # why serving stopped
        self.disarmed = False  # the UAV disarmed after sharing (session over)
        self.errors = 0
        self.uav_host: str | None = None
        self.telemetry_host: str | None = None
        self.last_poll_at: float | None = None  # monotonic time of the last poll since sharing
        self.warnings = net.RateLimitedLog(log)
        self.refusals = net.RateLimitedLog(log)
        self._complete_told = False
        self._start_told = False
        self._score_told = False
        self._credited = False  # a poll was credited (the testbed's download text exists)
        # the testbed's own state (clock=wall): its t1 of the last telemetry, its "stop"
        self._shared_t: float | None = None
        self._t1 = 0.0
        self._climbed = False
        self._arm_seen = False
        self._disarm_seen = False
        self._stop = -99
        self._complete_learned = False
        self._told: dict[str, float | bool] | None = None
        self._off_at: float | None = None

    # -- telemetry ---------------------------------------------------------------------------

    def telemetry(self, text: str, peer: str = "") -> str:
        """Take one telemetry message; the reply the testbed's controller gives.

        The first sender of a valid message owns the session's telemetry (and, before any
        poll was served, the session's polls); garbage claims nothing."""
        with self._lock:
            owner = self.telemetry_host or self.uav_host
            if owner is not None and peer != owner:
                return self._refuse(
                    f"telemetry from {peer}: the session's comes from {owner}", "Error: "
                )
        try:
            message = protocol.parse_telemetry(text)
        except SkymuleError as exc:
            with self._lock:
                return self._refuse(str(exc), "Error: ")
        with self._lock:
            if self.telemetry_host is None:
                self.telemetry_host = peer
            if self.dialect == "testbed":
                for problem in protocol.testbed_telemetry_problems(text):
                    self._warn(f"telemetry from {peer}: {problem}")
            self._take(message)
            if self.clock == "wall":
                return self._judge(self.testbed_clock.now())
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
                start = f"Download starts at {protocol.stamp(self.shared_at)}"
                if self.dialect == "testbed":  # the testbed prints it and sends "None"
                    log.info("%s", start)
                    return protocol.NOTHING_NEW
                return start
            return protocol.NOTHING_NEW

    def _take(self, message: protocol.Telemetry) -> None:
        self._position = telemetry_position(message, self.mission.frame, self._position)
        if message.armed is not None:
            self._armed = message.armed
            self._note_arm(message.armed)
        self._observe(message.alt_m, message.armed)

    def _note_arm(self, armed: bool) -> None:
        if self.clock == "poll" and not armed and self.shared_at is not None:
            self.disarmed = True
            self.stopped = self.stopped or "disarmed"

    def _observe(self, alt_m: float | None, armed: bool | None) -> None:
        """The testbed's session state from one observation: serving goes on once the UAV was
        above 24 m ("stop" 0) until it disarms after having armed ("stop" 1)."""
        if alt_m is not None and alt_m > SHARE_ALTITUDE_M and not self._climbed:
            self._climbed, self._stop = True, 0
        if armed is True:
            self._arm_seen = True
        elif armed is False and self._arm_seen:
            self._disarm_seen = True
        if self._arm_seen and self._disarm_seen:
            self._stop = 1
            if self.clock == "wall" and self.shared_at is not None:
                self.disarmed = True

    def _judge(self, now: float) -> str:
        """The testbed's telemetry reply at ``now``: t1, completion and the score line."""
        if self._shared_t is None or self.shared_at is None:
            return protocol.NOT_STARTED
        self._t1 = round(now - self._shared_t, 6)
        complete = self._complete()
        self._complete_learned = self._complete_learned or complete
        if self._told is not None:
            return protocol.NOTHING_NEW
        window_closed = self._t1 > self.window_s
        if not window_closed and not self._start_told:
            self._start_told = True
            log.info("Download starts at %s", protocol.stamp(self.shared_at))
        if window_closed or complete or self._stop == 1:
            self._told = self._testbed_parts(self._t1)
            self._off_at = now
            self.stopped = (
                f"window of {self.window_s:g} s closed"
                if window_closed
                else ("all data downloaded" if complete else "disarmed")
            )
            return protocol.format_score(
                float(self._told["aadm_t1_s"]),
                float(self._told["aadm_s1"]),
                float(self._told["aadm_s2"]),
                float(self._told["aadm_score"]),
                window_closed=window_closed,
            )
        return protocol.NOTHING_NEW

    def _testbed_parts(self, t1_s: float) -> dict[str, float | bool]:
        complete = self._complete()
        total = float(self.volumes_bit.sum())
        s1 = max(0.0, self.window_s - t1_s) if complete else 0.0
        s2 = 100.0 * float(self.received_bit.sum()) / total if total > 0 else 100.0
        return {
            "aadm_t1_s": t1_s,
            "aadm_s1": s1,
            "aadm_s2": s2,
            "aadm_complete": complete,
            "aadm_score": s1 + s2,
        }

    # -- one poll ----------------------------------------------------------------------------

    def request(
        self, text: str, peer: str = "", round_start: float | None = None
    ) -> tuple[str, PollSnapshot | None]:
        """Answer one request: (reply, snapshot for the tower choice; None: no choice follows).

        ``round_start``: when the testbed's poll loop began the round that accepted this
        poll (clock=wall, :class:`Pacer`): a round begun after the score was out is "off"."""
        with self._lock:
            if text.strip() != protocol.REQUEST:
                if self.dialect == "lenient":
                    return self._refuse(
                        f"request {text.strip()[:40]!r} is not allowed; expected "
                        f"{protocol.REQUEST!r}",
                        f"{protocol.PREFIX} ",
                    ), None
                self._warn(
                    f"request {text[:40]!r} from {peer} is not {protocol.REQUEST!r}: served "
                    "as a poll, as the testbed does"
                )
            refusal = self._stranger_locked(peer)
            if refusal is not None:
                return refusal, None
            if self._off(round_start):
                return protocol.OFF_REPLY, None
            position, armed = self._position, self._armed
            if self.position_source is not None:
                position, armed = self.position_source()
                self._note_arm(armed)
                self._observe(float(position[2]), armed)
            snr, where = self.feed.snr_db(position, self._requests)
            self._requests += 1
            known = position is not None or self.feed.mission.source is None
            if position is None and self.feed.mission.source is None:
                self._observe(float(where[2]), None)  # a trace: its own altitude
            if self.clock == "wall":
                if self.telemetry_host is None:  # nobody sends telemetry: judge at each poll
                    self._judge(self.testbed_clock.now())
                altitude = float(where[2]) if known else 0.0
                ok = (altitude > SHARE_ALTITUDE_M and self._t1 <= self.window_s) or self._stop == 0
                waiting = not ok
            else:
                waiting = self.disarmed or (
                    self.shared_at is None and not (known and where[2] > SHARE_ALTITUDE_M)
                )
            if waiting:
                return protocol.WAIT_REPLY, PollSnapshot(snr, False, waiting=True)
            self.last_poll_at = time.monotonic()
            if self.shared_at is None:
                self.shared_at = datetime.now()
                self._shared_t = self.testbed_clock.now()
                self.uav_host = peer
                self._open_log()
                head = protocol.format_volumes(self.volumes_bit / BITS_PER_MBIT)
            elif self._completion_known() and not self._complete_told:
                self._complete_told = True
                head = "download_complete:1"
            elif self.dialect == "testbed" and not self._credited:
                head = "download:None"  # the testbed has no download text before a credit
            else:
                head = protocol.format_downloads(self.received_bit / BITS_PER_MBIT)
            serving = True if self.clock == "wall" else self._serving()
            return f"{head};{protocol.format_snr(snr)}", PollSnapshot(snr, serving)

    def stranger(self, peer: str) -> str | None:
        """The refusal for a poll from an address that is not the session's UAV, else None
        (checked before a poll waits for its turn, so strangers cannot take the UAV's)."""
        with self._lock:
            return self._stranger_locked(peer)

    def _stranger_locked(self, peer: str) -> str | None:
        owner = self.uav_host or self.telemetry_host
        if owner is None or peer == owner:
            return None
        return self._refuse(
            f"poll from {peer}: this session's UAV is at {owner}", f"{protocol.PREFIX} "
        )

    def _off(self, round_start: float | None) -> bool:
        """Whether the testbed's poll loop is "off": its round began after the score line."""
        off = self._off_at
        if self.clock != "wall" or off is None:
            return False
        return round_start is None or round_start >= off

    def _completion_known(self) -> bool:
        # the testbed learns of completion from a telemetry message; the poll clock at once
        return self._complete_learned if self.clock == "wall" else self._complete()

    def _tower(self, text: str) -> int | None:
        """The tower a choice names (None: invalid), by the dialect's rule."""
        if self.dialect == "lenient":
            try:
                return parse_tower_id(text, self.n_towers, "tower choice")
            except SkymuleError as exc:
                log.warning("bad input from the UAV: %s", exc)
                return None
        if text in {str(k) for k in range(1, self.n_towers + 1)}:
            return int(text)
        cell = text.strip()
        if cell.isdigit() and 1 <= int(cell) <= self.n_towers:
            self._warn(
                f"tower id {text!r}: the testbed answers {protocol.INVALID_TOWER!r} and "
                f"downloads nothing (it compares the bare bytes); send {cell!r}"
            )
        else:
            self._warn(
                f"tower id {text[:20]!r} is not 1..{self.n_towers}: {protocol.INVALID_TOWER}"
            )
        return None

    def choose(self, text: str, snapshot: PollSnapshot) -> str:
        """Account the tower the UAV named for the poll ``snapshot`` came from."""
        if snapshot.waiting:
            return protocol.WAIT_REPORT
        with self._lock:
            tower = self._tower(text)
            if tower is None:
                self.errors += 1
                # the testbed's wall clock runs on: the poll counts toward t1
                testbed_poll = self.dialect == "testbed" and self.clock == "poll"
                if testbed_poll and snapshot.serving and self._serving():
                    self._count_poll(0.0)
                return protocol.INVALID_TOWER
            index = tower - 1
            left = self.volumes_bit[index] - self.received_bit[index]
            serving = snapshot.serving and (self.clock == "wall" or self._serving())
            when = self._report_time(serving)
            full = left <= self.volumes_bit[index] * COMPLETE_RTOL
            bits = 0.0
            if serving:  # the SNR this poll reported, as the controller does
                bits = float(poll_download_bit(snapshot.snr_db[index], left, self.poll_s))
                self.received_bit[index] += bits
                self._credited = self._credited or not full
                self._count_poll(bits)
            if full:
                return protocol.format_no_data_left(when, tower)
            return protocol.format_report(
                when,
                tower,
                float(snapshot.snr_db[index]),
                bits / BITS_PER_MBIT / self.poll_s,
                self.received_bit[index] / BITS_PER_MBIT,
            )

    def _count_poll(self, bits: float) -> None:
        self.per_poll_bit.append(bits)
        self.served_polls += 1
        self._write_row()
        if self.clock == "wall":
            return
        if self._complete():
            self.stopped = "all data downloaded"
        elif self.served_polls >= window_slots(self.window_s, self.poll_s):
            self.stopped = f"window of {self.window_s:g} s closed"

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
        """The score parts of the session so far (clock=wall: the ones the telemetry was told,
        or those of this moment)."""
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
        if self.clock == "wall":
            if self._told is not None:
                return dict(self._told)
            if self._shared_t is None:
                return self._testbed_parts(0.0)
            return self._testbed_parts(round(self.testbed_clock.now() - self._shared_t, 6))
        per_poll = np.asarray(self.per_poll_bit, float)
        return aadm_score_one(per_poll, float(self.volumes_bit.sum()), self.poll_s, self.window_s)

    def _complete(self) -> bool:
        return bool(np.all(self.received_bit >= self.volumes_bit * (1 - COMPLETE_RTOL)))

    def _serving(self) -> bool:
        return self.shared_at is not None and self.stopped is None

    def _refuse(self, message: str, prefix: str) -> str:
        self.errors += 1
        self.refusals.warning(f"refused: {message}")
        return f"{prefix}{message}"

    def _warn(self, message: str) -> None:
        self.warnings.warning(f"would fail on the testbed: {message}")

    def _report_time(self, serving: bool) -> datetime:
        if self.clock == "wall":
            return self._wall_time()
        return self._poll_time(self.served_polls if serving else self.served_polls - 1)

    def _wall_time(self) -> datetime:
        shared = self.shared_at or datetime.now()
        since = 0.0 if self._shared_t is None else self.testbed_clock.now() - self._shared_t
        return shared + timedelta(seconds=since)

    def _poll_time(self, poll: int) -> datetime:
        shared = self.shared_at or datetime.now()
        return shared + timedelta(seconds=max(poll, 0) * self.poll_s)

    def _open_log(self) -> None:
        if self._log_path is not None and self._writer is None:
            self._writer = DownloadLogWriter(self._log_path, self.n_towers)

    def _write_row(self) -> None:
        if self._writer is not None:
            when = (
                self._wall_time()
                if self.clock == "wall"
                else self._poll_time(self.served_polls - 1)
            )
            self._writer.write(when, self.received_bit / BITS_PER_MBIT)


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


def one_recv(data: bytes) -> net.Verdict:
    """The testbed's reading: whatever one ``recv(1024)`` returns is the message."""
    return "whole"


def _serve_poll(core: ControllerCore) -> Callable[[socket.socket, str], None]:
    testbed = core.dialect == "testbed"
    request = one_recv if testbed else request_verdict
    tower = one_recv if testbed else tower_verdict(core.n_towers)

    def handle(sock: socket.socket, peer: str) -> None:
        data = net.receive(sock, request, first_byte_s=net.FIRST_BYTE_S)
        if data is None:
            return
        refusal = core.stranger(peer)
        if refusal is not None:  # before waiting for a turn: strangers cannot take the UAV's
            sock.sendall(refusal.encode())
            return
        round_start = core.pacer.admit() if core.pacer is not None else None
        reply, snapshot = core.request(data.decode("utf-8", "replace"), peer, round_start)
        sock.sendall(reply.encode())
        if snapshot is None:
            return
        choice = net.receive(sock, tower)
        if choice is None:
            log.info("UAV disconnected before naming a tower; poll not counted")
            return
        sock.sendall(core.choose(choice.decode("utf-8", "replace"), snapshot).encode())

    return handle


def _serve_telemetry(core: ControllerCore) -> Callable[[socket.socket, str], None]:
    line = one_recv if core.dialect == "testbed" else net.text_line

    def handle(sock: socket.socket, peer: str) -> None:
        data = net.receive(sock, line, first_byte_s=net.FIRST_BYTE_S)
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
    of kind ``error`` or ``off`` (the score is out) is returned with an empty report."""
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
        if reply.kind in ("error", "off"):
            return reply, ""
        sock.sendall(str(choose(reply)).encode())
        report = net.receive_all(sock, timeout_s).decode("utf-8", "replace").strip()
        if not report:  # the controller always answers the tower id: the link broke
            raise SkymuleError(f"controller {host}:{port} closed the connection without a report")
        return reply, report


def send_telemetry(host: str, port: int, message: str, timeout_s: float = 5.0) -> str:
    """One telemetry message (newline-terminated, which the testbed tolerates); the reply."""
    return net.exchange(host, port, message + "\n", timeout_s).strip()

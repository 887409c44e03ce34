"""Any skymule policy as the AADM UAV-side agent.

:class:`AadmAgent` is the plain Python entry point: call ``step(snr_db, downloaded_mbit,
position_m)`` once a second (e.g. from your own aerpawlib state machine) and get the tower to
name and the point to fly to. It builds the policy's MissionContext exactly as the engine does
(:func:`policy_context`), turns what the controller reported into an
:class:`~skymule.policies.base.Observation` (rates from the scenario's rate table, data left
= volume - downloaded) and applies the engine's motion rules to the policy's ``goto_m``:
a goal outside the geofence becomes the nearest fence point, and with ``return_home`` the goal
becomes home whenever flying on would leave too little time to get back (the invariant of
:mod:`skymule.sim.autonomous`). On a fixed trajectory it flies the scenario's path one sample
a slot, holding where the policy hovers.

Two transports drive it with a :class:`~skymule.aadm.vehicle.Vehicle`: the challenge's TCP
bytes (:func:`fly_tcp`: telemetry, then the poll, as the testbed's UAV and its controller
exchange them) and the challenge's agent<->comm files (:func:`run_file_agent`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from skymule.aadm import files, net, protocol
from skymule.aadm.controller import poll_once, send_telemetry
from skymule.aadm.protocol import NOT_HEARD_DB, Reply
from skymule.aadm.score import UNREADABLE_SNR_DB, poll_download_bit
from skymule.aadm.vehicle import Vehicle
from skymule.errors import SkymuleError
from skymule.policies.base import BatchObservation, BatchPolicy, MissionContext, Policy
from skymule.policies.batched import as_batch_policy
from skymule.sim.columns import check_actions
from skymule.sim.run import mission_context
from skymule.units import BITS_PER_MBIT
from skymule.world import Mission

log = logging.getLogger("skymule.aadm.agent")

#: The UAV is "at home" within this distance before it lands [m].
HOME_TOLERANCE_M = 0.5


def _frozen(values: np.ndarray) -> np.ndarray:
    values.flags.writeable = False
    return values.view()


def policy_context(mission: Mission) -> MissionContext:
    """The MissionContext the engine gives a policy for ``mission``."""
    return mission_context(mission)


@dataclass(frozen=True)
class AgentStep:
    """One decision: the tower to name (1..N), where to fly, and the policy's own choice.

    ``goto_m`` is where the engine's UAV is at the end of this slot; ``lead_m`` where it is
    at the end of the next one, along the same path: the goal for a vehicle that flies in real
    time (a MAVLink autopilot), which then never stops at the slot's end point to wait for the
    next poll (it lagged the engine by the poll's own time every slot, and ended up elsewhere).
    """

    tower_id: int
    goto_m: tuple[float, float] | None
    serve: int | None
    lead_m: tuple[float, float] | None = None


class AadmAgent:
    """A skymule policy behind the challenge's once-a-second interface."""

    def __init__(self, mission: Mission, policy: Policy | BatchPolicy) -> None:
        self.mission = mission
        self.policy = as_batch_policy(policy)  # a batch of one
        self.autonomous = mission.mode == "autonomous"
        self.context = policy_context(mission)
        self._engine = None
        if self.autonomous:  # the engine's own motion rule, for one UAV
            from skymule.sim.autonomous import AutonomousEngine

            self._engine = AutonomousEngine([mission], detail=False)
        self.volumes_bit: np.ndarray | None = None
        self.slot = 0
        self._track_sample = 0

    @property
    def n_towers(self) -> int:
        """How many towers (the mission's sensors) the agent chooses among."""
        return self.mission.n_sensors

    @property
    def finished(self) -> bool:
        """True once the mission's slots are used up."""
        return self.slot >= self.context.n_slots

    def home_xy(self) -> tuple[float, float]:
        """(x, y) of home [m]: the mission's home when autonomous, else the origin."""
        home = self.mission.home_m if self.autonomous else None
        home = np.zeros(2) if home is None else home
        return float(home[0]), float(home[1])

    def start(self, volumes_mbit: np.ndarray) -> None:
        """Reset the policy for the volumes the controller shared (slot 0 is the next step)."""
        volumes = np.asarray(volumes_mbit, float)
        if volumes.shape != (self.n_towers,):
            raise SkymuleError(
                f"volumes: {volumes.size} values for the scenario's {self.n_towers} towers"
            )
        self.volumes_bit = volumes * BITS_PER_MBIT
        self.policy.reset([replace(self.context, buffers_bit=self.volumes_bit.copy())])
        self.slot, self._track_sample = 0, 0

    def step(
        self,
        snr_db: np.ndarray,
        downloaded_mbit: np.ndarray,
        position_m: np.ndarray,
        volumes_mbit: np.ndarray | None = None,
        *,
        remaining_bit: np.ndarray | None = None,
    ) -> AgentStep:
        """One slot: SNR per tower [dB] (-99: not heard; NaN: unreadable, 0 dB), cumulative
        Mbit downloaded per tower, UAV position [m] -> tower id and goal.

        The first call starts the mission with ``volumes_mbit`` (default: the scenario's
        buffers) unless :meth:`start` was called. ``remaining_bit`` (N,), when given, is the
        data left per tower to the bit and takes the place of volume - downloaded.
        """
        if self.volumes_bit is None:
            default = self.mission.buffers_bit / BITS_PER_MBIT
            self.start(default if volumes_mbit is None else volumes_mbit)
        assert self.volumes_bit is not None
        snr = np.asarray(snr_db, float).reshape(self.n_towers)
        heard = np.where(np.isnan(snr), UNREADABLE_SNR_DB, snr)
        seen = np.where(heard <= NOT_HEARD_DB, -np.inf, heard)
        if remaining_bit is None:
            remaining_bit = self.volumes_bit - np.asarray(downloaded_mbit, float) * BITS_PER_MBIT
        remaining = np.maximum(np.asarray(remaining_bit, float).reshape(self.n_towers), 0.0)
        position = np.asarray(position_m, float).reshape(3)
        action = self.policy.act(
            BatchObservation(
                slot=_frozen(np.array([self.slot], np.int64)),
                active=_frozen(np.ones(1, bool)),
                position_m=_frozen(position[None].copy()),
                snr_db=_frozen(seen[None]),
                rate_bps=_frozen(self.mission.rate_bps(seen)[None]),
                remaining_bit=_frozen(remaining[None]),
            )
        )
        serve = int(check_actions(action, 1, self.n_towers, self.policy.name)[0])
        hover = action.hover is not None and bool(np.asarray(action.hover)[0])
        goto_m = None if action.goto_m is None else np.asarray(action.goto_m, float)[0]
        goto, lead = self._goal(goto_m, hover, position)
        self.slot += 1
        tower = serve if serve >= 0 else self._idle_tower(remaining, seen)
        return AgentStep(tower + 1, goto, None if serve < 0 else serve, lead)

    def _idle_tower(self, remaining: np.ndarray, snr: np.ndarray) -> int:
        # the protocol needs a tower every poll: name an empty one, so that nothing is
        # downloaded when the policy serves nobody (as in the engine); else the weakest link
        empty = np.flatnonzero(remaining <= 0)
        return int(empty[0]) if empty.size else int(np.argmin(snr))

    def _goal(
        self, goto_m: np.ndarray | None, hover: bool, position: np.ndarray
    ) -> tuple[tuple[float, float] | None, tuple[float, float] | None]:
        """(end of this slot, end of the next one if the goal stays) by the engine's rules."""
        if not self.autonomous:
            track = self.mission.track
            if track is None:
                return None, None
            if not hover:
                self._track_sample = min(self._track_sample + 1, track.n_samples - 1)
            target = track.position_m[self._track_sample]
            ahead = track.position_m[
                min(self._track_sample + (0 if hover else 1), track.n_samples - 1)
            ]
            return (float(target[0]), float(target[1])), (float(ahead[0]), float(ahead[1]))
        # the engine's own motion rule (fence, speed cap, return home): one step ahead
        assert self._engine is not None
        goal = np.full((1, 2), np.nan) if goto_m is None else goto_m.reshape(1, 2)
        moved = self._engine.moves_from(position[None, :2], goal, np.array([self.slot]))[0]
        ahead = self._engine.moves_from(moved[None], goal, np.array([self.slot + 1]))[0]
        return (float(moved[0]), float(moved[1])), (float(ahead[0]), float(ahead[1]))


# ---------------------------------------------------------------------------
# Driving a vehicle
# ---------------------------------------------------------------------------

#: Failed polls in a row the agent tries again before it returns to launch.
POLL_RETRIES = 12
#: Wall seconds between those tries: 12 x 1 s outlasts the controller's 10-s message deadline
#: (and its 2-s first-byte deadline), so a crowd of idle connections, closed at that deadline,
#: cannot make the UAV give up.
RETRY_WAIT_S = 1.0
#: Slots the vehicle may take to fly home and land once the controller is lost.
LANDING_SLOTS = 2000
#: The agent polls once the vehicle is this close to its take-off altitude [m] ...
CLIMB_TOLERANCE_M = 0.5
#: ... or after this many slots of climbing, whichever comes first.
CLIMB_SLOTS = 600


@dataclass
class FlightRecord:
    """What an agent run did, poll by poll."""

    positions_m: list[np.ndarray] = field(default_factory=list)
    towers: list[int] = field(default_factory=list)
    reports: list[str] = field(default_factory=list)
    polls: int = 0
    climb_slots: int = 0  # slots spent climbing before the first poll
    share_poll: int | None = None
    rejoined: bool = False
    score_line: str | None = None  # the controller's "T1: ..., Score:..." telemetry reply

    def end_distance_to(self, home_xy: tuple[float, float]) -> float:
        last = self.positions_m[-1] if self.positions_m else np.zeros(3)
        return float(np.hypot(last[0] - home_xy[0], last[1] - home_xy[1]))


@dataclass
class Ledger:
    """The data left per tower [bit], kept by the UAV from the controller's reports.

    The testbed reports the downloads with 2 decimals of Mbit, too coarse for a policy that
    plans to the bit; each served report names the tower and the rate it credited, so the
    UAV redoes the controller's own sum (:func:`~skymule.aadm.score.poll_download_bit` at
    the SNR the poll reported) and takes the report's total instead whenever the two
    disagree at the report's precision.
    """

    volumes_bit: np.ndarray
    remaining_bit: np.ndarray

    @classmethod
    def start(cls, volumes_mbit: np.ndarray, downloaded_mbit: np.ndarray | None = None) -> Ledger:
        volumes = np.asarray(volumes_mbit, float) * BITS_PER_MBIT
        got = np.zeros_like(volumes) if downloaded_mbit is None else downloaded_mbit
        return cls(volumes, np.maximum(volumes - np.asarray(got, float) * BITS_PER_MBIT, 0.0))

    def sync(self, downloaded_mbit: np.ndarray) -> None:
        """Take the ``download:`` reply's totals where the ledger is off by more than their
        2 decimals (a report lost with a failed poll that the controller still counted)."""
        reported = np.asarray(downloaded_mbit, float) * BITS_PER_MBIT
        kept = self.volumes_bit - self.remaining_bit
        off = np.abs(kept - reported) > 0.0051 * BITS_PER_MBIT
        self.remaining_bit = np.where(
            off, np.maximum(self.volumes_bit - reported, 0.0), self.remaining_bit
        )

    def credit(self, report: protocol.Report, snr_db: np.ndarray, slot_s: float) -> None:
        if not report.served or report.tower is None or not 1 <= report.tower <= len(snr_db):
            return
        index = report.tower - 1
        left = self.remaining_bit[index]
        bits = float(poll_download_bit(snr_db[index], left, slot_s))
        if f"{bits / BITS_PER_MBIT / slot_s:.2f}" == f"{report.rate_mbit:.2f}":
            self.remaining_bit[index] = left - bits
        else:  # an SNR on a CQI step at the report's 6 decimals: trust the controller's sum
            got = report.received_mbit * BITS_PER_MBIT
            self.remaining_bit[index] = max(float(self.volumes_bit[index]) - got, 0.0)


class _Pilot:
    """Take-off, the mission, return to launch and landing, shared by both transports."""

    def __init__(self, agent: AadmAgent, vehicle: Vehicle, altitude_m: float) -> None:
        self.agent, self.vehicle = agent, vehicle
        self.altitude_m = altitude_m
        self.done = False  # mission over: fly home and land
        self.record = FlightRecord()

    def decide(
        self,
        kind: str,
        snr: np.ndarray | None,
        volumes_mbit: np.ndarray | None,
        remaining_bit: np.ndarray,
    ) -> int:
        position = self.vehicle.position_m()
        goto: tuple[float, float] | None = None
        if kind in ("wait", "error", "") or self.done or snr is None or volumes_mbit is None:
            tower = 1  # not served: any tower will do
        else:
            if self.agent.volumes_bit is None:
                self.record.share_poll = self.record.polls
                self.agent.start(volumes_mbit)
            step = self.agent.step(snr, np.zeros(len(snr)), position, remaining_bit=remaining_bit)
            tower, goto = step.tower_id, step.goto_m
            if getattr(self.vehicle, "real_time", False) and step.lead_m is not None:
                goto = step.lead_m  # it flies on while the next poll is made
            if kind == "download_complete" or self.agent.finished:
                self.done = True
        if self.done:
            goto = self.agent.home_xy()
        if goto is not None:
            self.vehicle.goto(goto)
        self.record.positions_m.append(position)
        self.record.towers.append(tower)
        return tower

    def advance(self, dt_s: float) -> bool:
        """Let ``dt_s`` pass; True once the vehicle has landed and disarmed after the mission."""
        self.record.polls += 1
        if self.done and self.vehicle.armed:
            here = self.vehicle.position_m()
            home = self.agent.home_xy()
            if np.hypot(here[0] - home[0], here[1] - home[1]) <= HOME_TOLERANCE_M:
                self.vehicle.land()
        self.vehicle.tick(dt_s)
        return self.done and not self.vehicle.armed

    def return_to_launch(self, dt_s: float, pace_s: float) -> None:
        """Fly home and land without the controller (bounded: ``LANDING_SLOTS``)."""
        self.done = True
        for _ in range(LANDING_SLOTS):
            if not self.vehicle.armed:
                return
            self.vehicle.goto(self.agent.home_xy())
            self.advance(dt_s)
            time.sleep(pace_s)


class _AgentFailed(Exception):
    """The agent itself failed inside a poll (not the link): land, then report it."""

    def __init__(self, error: SkymuleError) -> None:
        super().__init__(str(error))
        self.error = error


def telemetry_message(agent: AadmAgent, vehicle: Vehicle) -> str:
    """The vehicle's state as the testbed's telemetry line (lat/lon from the local frame)."""
    where = vehicle.position_m()
    lat, lon = agent.mission.frame.to_latlon(where[0], where[1])
    return protocol.format_telemetry(float(where[2]), vehicle.armed, float(lat), float(lon))


def fly_tcp(
    agent: AadmAgent,
    vehicle: Vehicle,
    host: str,
    port: int,
    telemetry_port: int | None,
    *,
    poll_s: float = 1.0,
    pace_s: float | None = None,
    altitude_m: float = 25.0,
    max_polls: int = 100_000,
    retries: int = POLL_RETRIES,
    retry_wait_s: float = RETRY_WAIT_S,
) -> FlightRecord:
    """Fly a mission against a controller over the challenge's TCP bytes.

    Each poll sends the vehicle's telemetry to ``telemetry_port`` (None: the controller knows
    the position another way), then polls ``port`` with a bare ``snr_dd`` and names a tower.
    ``poll_s`` is the time each poll stands for (the vehicle advances that much); the loop
    waits ``pace_s`` of wall time between polls (default ``poll_s``; 0 = as fast as
    possible). A failed poll is tried again up to ``retries`` times (``retry_wait_s`` apart);
    then the vehicle returns to launch and lands, and a one-line SkymuleError says why.
    A restarted agent rejoins a running session: without the ``vol:`` reply it takes the
    scenario's buffers as the volumes and the reply's downloads as done.
    """
    if poll_s <= 0:
        raise SkymuleError(f"poll_s = {poll_s:g}: each poll must stand for > 0 s")
    pilot = _Pilot(agent, vehicle, altitude_m)
    vehicle.takeoff(altitude_m)
    wait_s = poll_s if pace_s is None else pace_s
    n_towers = agent.n_towers
    book: list[Ledger] = []
    decided: list[int] = []  # this slot's tower, once the policy chose it

    def choose(reply: Reply) -> int:
        if decided:  # a poll tried again: the same tower, the policy is not asked twice
            return decided[0]
        try:
            decided.append(decide(reply))
        except SkymuleError as exc:  # the policy's own error: no retry, but land first
            raise _AgentFailed(exc) from exc
        return decided[0]

    def decide(reply: Reply) -> int:
        if reply.kind == "vol" and reply.values is not None and not book:
            book.append(Ledger.start(reply.values))
        elif reply.kind == "download" and book and reply.values is not None:
            book[0].sync(reply.values)
        elif reply.kind == "download" and not book:  # rejoining a running session
            book.append(Ledger.start(agent.mission.buffers_bit / BITS_PER_MBIT, reply.values))
            pilot.record.rejoined = True
            log.warning(
                "rejoined a running session: volumes from the scenario, downloads so far "
                "from the controller's reply"
            )
        ledger = book[0] if book else None
        volumes = None if ledger is None else ledger.volumes_bit / BITS_PER_MBIT
        remaining: np.ndarray = np.zeros(n_towers)
        if ledger is not None:
            remaining = ledger.remaining_bit.copy()
        if reply.kind == "download_complete":
            remaining = np.zeros(n_towers)
        return pilot.decide(reply.kind, reply.snr_db, volumes, remaining)

    def one_poll() -> tuple[Reply, str]:
        if telemetry_port is not None:
            answer = send_telemetry(host, telemetry_port, telemetry_message(agent, vehicle))
            if answer.startswith("T1:"):  # the score is out: the mission is over
                pilot.record.score_line = answer
                pilot.done = True
        reply, report = poll_once(host, port, choose, n_towers)
        if reply.kind == "off":  # the testbed's controller after the score: fly home, land
            pilot.done = True
            pilot.decide(reply.kind, None, None, np.zeros(n_towers))
            return reply, report
        if reply.kind == "error":
            raise SkymuleError(f"controller {host}:{port} refused the poll: {reply.text}")
        if book and reply.snr_db is not None:
            book[0].credit(protocol.parse_report(report), reply.snr_db, agent.mission.slot_s)
        return reply, report

    _climb(agent, vehicle, host, telemetry_port, altitude_m, poll_s, wait_s, pilot.record)
    failures = 0
    for _ in range(max_polls):
        started = time.monotonic()
        try:
            _, report = one_poll()
            failures = 0
        except _AgentFailed as failed:
            pilot.return_to_launch(poll_s, wait_s)
            raise failed.error from None
        except (OSError, SkymuleError) as exc:
            if pilot.done:  # the mission is over: fly home and land without the controller
                pilot.return_to_launch(poll_s, wait_s)
                break
            failures += 1
            if failures > retries:
                pilot.return_to_launch(poll_s, wait_s)
                why = "no controller listening" if isinstance(exc, ConnectionRefusedError) else exc
                away = pilot.record.end_distance_to(agent.home_xy())
                raise SkymuleError(
                    f"controller {host}:{port}: {why}; gave up after {retries} retries, "
                    f"returned to launch and landed {away:.1f} m from it"
                ) from None
            log.warning("poll failed (%s); trying again (%d of %d)", exc, failures, retries)
            time.sleep(retry_wait_s)
            continue
        pilot.record.reports.append(report)
        decided.clear()
        if pilot.advance(poll_s):
            if telemetry_port is not None:  # the controller sees the disarm: session over
                try:
                    answer = send_telemetry(host, telemetry_port, telemetry_message(agent, vehicle))
                    pilot.record.score_line = pilot.record.score_line or (
                        answer if answer.startswith("T1:") else None
                    )
                except OSError:
                    log.info("controller gone before the final telemetry")
            break
        time.sleep(max(0.0, wait_s - (time.monotonic() - started)))
    return pilot.record


def _climb(
    agent: AadmAgent,
    vehicle: Vehicle,
    host: str,
    telemetry_port: int | None,
    altitude_m: float,
    poll_s: float,
    wait_s: float,
    record: FlightRecord,
) -> None:
    """Climb to the take-off altitude before the first poll, sending telemetry meanwhile.

    The controller shares the volumes (slot 0, t1 = 0) at the first poll above 24 m; polled
    during the climb, the UAV would get them at 25 m with a few slots of climbing ahead, in
    which it cannot fly off: a policy that heads away at once (the README's
    LargestBufferFirst) then flew 2 slots behind ``skymule run``, whose slot 0 is at the
    mission altitude. Polling once at altitude makes slot 0 the same in both; on the testbed
    it only starts t1 at the mission altitude instead of 24 m.
    """
    quiet = net.RateLimitedLog(log, every_s=10.0)
    for _ in range(CLIMB_SLOTS):
        if vehicle.position_m()[2] >= altitude_m - CLIMB_TOLERANCE_M:
            return
        started = time.monotonic()
        if telemetry_port is not None:
            try:
                send_telemetry(host, telemetry_port, telemetry_message(agent, vehicle))
            except OSError as exc:
                quiet.warning(f"telemetry to {host}:{telemetry_port} failed while climbing: {exc}")
        vehicle.tick(poll_s)
        record.climb_slots += 1
        time.sleep(max(0.0, wait_s - (time.monotonic() - started)))


def run_file_agent(
    agent: AadmAgent,
    vehicle: Vehicle,
    folder: Path,
    *,
    poll_s: float = 1.0,
    pace_s: float | None = None,
    altitude_m: float = 25.0,
    max_polls: int = 100_000,
    should_stop: Callable[[], bool] = lambda: False,
    telemetry: tuple[str, int] | None = None,
) -> FlightRecord:
    """Beside the challenge's comm process: read ss/dv/dd/tn.txt, write bc.txt, each poll.

    Each poll is one slot of ``poll_s`` for the vehicle; the loop waits ``pace_s`` of wall
    time between polls (default ``poll_s``; 0 = as fast as possible). ``telemetry``: the
    controller's telemetry (host, port), sent the vehicle's state each poll as the UAV's own
    telemetry process does on the testbed (None: something else sends it), from the mission
    altitude on (the vehicle climbs first); the score line it gets back ends the mission
    (``record.score_line``).
    """
    if poll_s <= 0:
        raise SkymuleError(f"poll_s = {poll_s:g}: each poll must stand for > 0 s")
    pilot = _Pilot(agent, vehicle, altitude_m)
    vehicle.takeoff(altitude_m)
    n_towers = agent.n_towers
    # climb first, telling nobody: the controller shares the volumes (slot 0) at the first
    # poll after the telemetry put the UAV above 24 m, here at the mission altitude
    pace = poll_s if pace_s is None else pace_s
    _climb(agent, vehicle, "", None, altitude_m, poll_s, pace, pilot.record)
    quiet = net.RateLimitedLog(log, every_s=10.0)
    for _ in range(max_polls):
        if should_stop():
            break
        started = time.monotonic()
        if telemetry is not None:
            try:
                answer = send_telemetry(*telemetry, telemetry_message(agent, vehicle))
            except OSError as exc:
                quiet.warning(f"telemetry to {telemetry[0]}:{telemetry[1]} failed: {exc}")
            else:
                if answer.startswith("T1:"):
                    pilot.record.score_line = pilot.record.score_line or answer
                    pilot.done = True
        try:
            snr = files.read_tower_file(folder / files.SNR_FILE, n_towers)
        except SkymuleError as exc:
            log.info("no SNR yet: %s", exc)
            snr = None
        if snr is not None:
            volumes = _optional(lambda: files.read_tower_file(folder / files.VOLUME_FILE, n_towers))
            done = bool(_optional(lambda: files.read_done_file(folder / files.DONE_FILE)))
            got = _optional(lambda: files.read_tower_file(folder / files.DOWNLOADED_FILE, n_towers))
            if volumes is not None and not volumes.any():  # the comm process's reset: not shared
                volumes = None
            kind = "wait" if volumes is None else ("download_complete" if done else "download")
            downloaded = got if got is not None else np.zeros(n_towers)
            remaining = np.zeros(n_towers)
            if volumes is not None and not done:
                remaining = (volumes - downloaded) * BITS_PER_MBIT
            tower = pilot.decide(kind, snr, volumes, remaining)
            files.write_choice_file(folder / files.CHOICE_FILE, tower)
        if pilot.advance(poll_s):
            if telemetry is not None:  # the controller sees the disarm: session over
                try:
                    answer = send_telemetry(*telemetry, telemetry_message(agent, vehicle))
                    if answer.startswith("T1:"):
                        pilot.record.score_line = pilot.record.score_line or answer
                except OSError:
                    log.info("controller gone before the final telemetry")
            break
        wait_s = poll_s if pace_s is None else pace_s
        time.sleep(max(0.0, wait_s - (time.monotonic() - started)))
    return pilot.record


def _optional(read: Callable[[], object]) -> np.ndarray | None:
    """A comm file's value, or None while the comm process has not written it (yet)."""
    try:
        value = read()
    except SkymuleError:
        return None
    return None if value is None else np.asarray(value)

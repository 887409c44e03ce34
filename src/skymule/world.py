"""From a validated scenario to the SI arrays the engine runs on.

:func:`build_mission` resolves everything a scenario refers to (site frame, geofence, sensor
positions, rate table, signal source, fixed path or recorded trace) and checks what needs
geometry to check (waypoints inside the geofence, trace columns present). Everything that
comes out is in metres, seconds, bits and dB.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np
from shapely.geometry import Point, Polygon, box

from skymule.errors import ScenarioError, SkymuleError
from skymule.faults.draws import FaultDraws, draw_faults, fault_rng
from skymule.flight.navigation import Navigator, hover_point
from skymule.flight.paths import Track, path_length_m, read_waypoints_csv, sample_path
from skymule.geo import LocalFrame, covers, sensor_positions_m
from skymule.io.qgc_plan import is_plan, plan_waypoints_m, scenario_fence
from skymule.limits import waypoint_problem
from skymule.radio.channel import mission_fading_db, signal_source
from skymule.radio.rates import RateTable, rate_bps, resolve_rate_table
from skymule.radio.sources import SignalSource
from skymule.rules import contract
from skymule.rules.defaults import AADM_WINDOW_S, HOVER_THRESHOLD, MAX_HOVER_S
from skymule.scenario import Scenario
from skymule.units import BITS_PER_MBIT

#: Half-width [m] of the square that stands in for a geofence when a scenario gives none.
UNFENCED_HALF_WIDTH_M = 1.0e6

#: Clearance [m] of hover points from the fence boundary (see ``hover_point``).
HOVER_MARGIN_M = 1.0


@dataclass(frozen=True)
class Mission:
    """Everything the engine needs for one mission, in SI units.

    Attributes:
        scenario: the validated scenario this was built from.
        frame: local east/north frame.
        fence: geofence polygon in local metres, or None.
        sensor_names: (N,) names.
        sensor_m: (N, 3) antenna positions [m]; NaN where a trace scenario gives none.
        buffers_bit: (N,) initial buffers [bit].
        slot_s: slot length [s].
        n_slots: number of slots T.
        rate_table: SNR -> spectral efficiency.
        bandwidth_hz: channel bandwidth [Hz].
        source: the signal source for positions the UAV chooses (model sources), or None.
        track: the fixed trajectory's samples with their SNR, or None (autonomous).
        fading_db: (T, N) small-scale fading [dB] added to the SNR the UAV observes in slot t,
            drawn once per mission (identical for every policy), or None. Peak rates (HGAD)
            come from the track without fading.
        mode: "fixed" (the UAV follows ``track``) or "autonomous" (the policy steers).
        home_m: (2,) home point [m] (``trajectory.home`` or the site origin), or None.
        hover_points_m: (N, 2) point inside the geofence each sensor is served from [m]
            (NaN where the sensor has no position), or None.
        visit_radius_m: a sensor counts as visited within this distance of its hover point [m].
        altitude_m: autonomous flight altitude [m].
        max_speed_mps: autonomous speed cap [m/s].
        return_home: autonomous: the UAV must be home when the mission ends.
        navigator: autonomous: in-fence shortest paths (a very large square without a fence);
            None on fixed trajectories.
        aadm_window_s: the AADM download window [s] (``mission.aadm_window_s``): slots that
            start at or after it serve nothing; None: every slot may serve (the AADM score
            still counts only the controller's 500 s).
        faults: the mission's fault draws (``[[faults]]``, drawn once, the same for every
            policy; ``docs/faults.md``), or None for a fault-free mission.

    A Mission is immutable: its arrays are read-only (writing raises), so policies and
    engines can share one Mission across runs.
    """

    scenario: Scenario
    frame: LocalFrame
    fence: Polygon | None
    sensor_names: tuple[str, ...]
    sensor_m: np.ndarray
    buffers_bit: np.ndarray
    slot_s: float
    n_slots: int
    rate_table: RateTable
    bandwidth_hz: float
    source: SignalSource | None
    track: Track | None
    fading_db: np.ndarray | None = None
    mode: str = "fixed"
    home_m: np.ndarray | None = None
    hover_points_m: np.ndarray | None = None
    visit_radius_m: float = 50.0
    altitude_m: float = 30.0
    max_speed_mps: float = 10.0
    return_home: bool = True
    navigator: Navigator | None = None
    aadm_window_s: float | None = None
    faults: FaultDraws | None = None

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
        if self.track is not None:
            self.track.position_m.flags.writeable = False
            self.track.snr_db.flags.writeable = False

    def for_run(
        self,
        scenario: Scenario,
        buffers_bit: np.ndarray,
        fading_db: np.ndarray | None,
        faults: FaultDraws | None,
    ) -> Mission:
        """This built mission flown as another run of it (the missions of a sweep that share a
        built track): ``dataclasses.replace`` of those four fields, the rest shared, at a
        tenth of its cost (a sweep makes one per mission; the shared fields were checked and
        frozen when this one was made). The arrays given are made read-only."""
        for values in (buffers_bit, fading_db):
            if values is not None:
                values.flags.writeable = False
        run = object.__new__(Mission)
        run.__dict__.update(
            self.__dict__,
            scenario=scenario,
            buffers_bit=buffers_bit,
            fading_db=fading_db,
            faults=faults,
        )
        return run

    @property
    def window_slots(self) -> int | None:
        """Slots that start before the download window closes, or None (no window)."""
        if self.aadm_window_s is None:
            return None
        return int(contract.window_slots(self.aadm_window_s, self.slot_s))

    @property
    def score_window_s(self) -> float:
        """The window the AADM score counts downloads in [s]."""
        return AADM_WINDOW_S if self.aadm_window_s is None else self.aadm_window_s

    @property
    def max_step_m(self) -> float:
        """Longest move in one slot, max_speed_mps * slot_s [m]."""
        return self.max_speed_mps * self.slot_s

    @property
    def n_sensors(self) -> int:
        """How many sensors the mission has (N)."""
        return len(self.sensor_names)

    def rate_bps(self, snr_db: np.ndarray) -> np.ndarray:
        """Rate [bit/s] for SNR [dB] of any shape (NaN: no link, rate 0)."""
        return rate_bps(self.rate_table, snr_db, self.bandwidth_hz)

    def peak_rate_bps(self) -> np.ndarray:
        """(N,) largest rate per sensor over the historical data (the track) [bit/s]."""
        if self.track is None:
            raise SkymuleError("peak rate needs a fixed trajectory or a recorded trace")
        return self.rate_bps(self.track.snr_db).max(axis=0)


MAX_SLOTS = 10_000_000
"""Longest mission and longest sampled path, in slots (115 days of 1-s slots)."""


def home_xy(scenario: Scenario, frame: LocalFrame) -> np.ndarray:
    """(2,) home point [m]: ``trajectory.home`` (lat/lon or [x, y]) or the site origin."""
    home = scenario.trajectory.home
    if home is None:
        return np.zeros(2)
    if isinstance(home, list):
        if len(home) != 2:
            raise ScenarioError(
                f"trajectory.home = {home!r}: give [x_m, y_m] (2 numbers) or {{ lat, lon }}"
            )
        return np.asarray(home, float)
    x_m, y_m = frame.to_local(home.lat, home.lon)
    return np.array([float(x_m), float(y_m)])


def fence_or_box(fence: Polygon | None) -> Polygon:
    """The geofence, or a very large square standing in for it when there is none."""
    if fence is not None:
        return fence
    half = UNFENCED_HALF_WIDTH_M
    return box(-half, -half, half, half)


def hover_points(fence: Polygon | None, sensor_m: np.ndarray) -> np.ndarray:
    """(N, 2) point inside the fence closest to each sensor [m] (NaN: no position)."""
    hover = np.full((len(sensor_m), 2), np.nan)
    for index, sensor in enumerate(sensor_m):
        if np.all(np.isfinite(sensor[:2])):
            xy = (float(sensor[0]), float(sensor[1]))
            hover[index] = xy if fence is None else hover_point(fence, xy, HOVER_MARGIN_M)
    return hover


def check_home_inside(fence: Polygon | None, home_m: np.ndarray) -> None:
    """Reject a home point outside the geofence (ScenarioError naming trajectory.home)."""
    if fence is not None and not fence.buffer(1e-6).covers(Point(home_m)):
        raise ScenarioError(
            f"trajectory.home = ({home_m[0]:.1f}, {home_m[1]:.1f}) m lies outside the "
            "geofence; the home point must be inside it"
        )


def check_duration(mission: Mission) -> None:
    """Reject an autonomous mission too short to reach the nearest hover point and return.

    Raises ScenarioError naming mission.duration_s, the time needed and why.
    """
    navigator, home, hover = mission.navigator, mission.home_m, mission.hover_points_m
    if navigator is None or home is None or hover is None:
        return
    reachable = np.all(np.isfinite(hover), axis=1)
    if not reachable.any():
        return
    distances = [
        navigator.travel_distance((float(home[0]), float(home[1])), (float(x), float(y)))
        for x, y in hover[reachable]
    ]
    nearest = int(np.argmin(distances))
    name = np.asarray(mission.sensor_names)[reachable][nearest]
    needed_slots = 2 * int(contract.slots_to_cover(distances[nearest], mission.max_step_m))
    if mission.n_slots < max(needed_slots, 1):
        raise ScenarioError(
            f"mission.duration_s = {mission.n_slots * mission.slot_s:g}: too short to fly from "
            f"home to the nearest hover point ({name}, {distances[nearest]:.0f} m) and back at "
            f"max_speed_mps = {mission.max_speed_mps:g}; needs >= "
            f"{needed_slots * mission.slot_s:g} s"
        )


def with_fence(mission: Mission, fence: Polygon | None) -> Mission:
    """``mission`` under another geofence: hover points and navigator rebuilt from it."""
    autonomous = mission.mode == "autonomous"
    if autonomous and mission.home_m is not None:
        check_home_inside(fence, mission.home_m)
    return replace(
        mission,
        fence=fence,
        hover_points_m=hover_points(fence_or_box(fence) if autonomous else fence, mission.sensor_m),
        navigator=Navigator(fence_or_box(fence)) if autonomous else None,
    )


def _n_slots(duration_s: float, slot_s: float) -> int:
    slots = duration_s / slot_s
    if slots > MAX_SLOTS:
        raise ScenarioError(
            f"mission.duration_s = {duration_s:g} with slot_s = {slot_s:g} makes {slots:.3g} "
            f"slots; at most {MAX_SLOTS:,} are allowed"
        )
    if abs(slots - round(slots)) > 1e-6 or round(slots) < 1:
        raise ScenarioError(
            f"mission.duration_s = {duration_s}: must be a positive whole number of "
            f"slots of slot_s = {slot_s}"
        )
    return round(slots)


def _check_path_samples(waypoints_m: np.ndarray, speed_mps: float, slot_s: float) -> None:
    samples = path_length_m(waypoints_m) / (speed_mps * slot_s)
    if samples > MAX_SLOTS:
        raise ScenarioError(
            f"trajectory.speed_mps = {speed_mps:g}: the {path_length_m(waypoints_m):.0f} m path "
            f"would take {samples:.3g} slots of {slot_s:g} s; at most {MAX_SLOTS:,} are allowed"
        )


def _waypoints(scenario: Scenario, frame: LocalFrame) -> np.ndarray:
    spec = scenario.trajectory.waypoints
    if spec is None:
        raise ScenarioError("trajectory.waypoints is required for mode = 'fixed' with a model")
    if is_plan(spec):  # a QGroundControl .plan (skymule.io.qgc_plan)
        waypoints = plan_waypoints_m(scenario.resolve_path(str(spec)), frame)
    elif isinstance(spec, str):
        waypoints = read_waypoints_csv(scenario.resolve_path(spec), frame.to_local)
    else:
        if any(len(point) != 3 for point in spec):
            raise ScenarioError("trajectory.waypoints: every waypoint must be [x_m, y_m, z_m]")
        waypoints = np.asarray(spec, float).reshape(-1, 3)
    if len(waypoints) < 2:
        raise ScenarioError(
            f"trajectory.waypoints has {len(waypoints)} point(s); a fixed path needs at least 2"
        )
    problem = waypoint_problem(waypoints)
    if problem is not None:  # a CSV or .plan file: the inline list was checked on loading
        raise ScenarioError(f"trajectory.waypoints ({spec}): {problem}")
    return waypoints


def _check_inside(fence: Polygon | None, points_m: np.ndarray, what: str) -> None:
    if fence is None:
        return
    inside = covers(fence, points_m[:, 0], points_m[:, 1], tolerance_m=0.5)
    if not inside.all():
        first = int(np.argmin(inside))
        x_m, y_m = points_m[first, :2]
        raise ScenarioError(
            f"{what}[{first}] = ({x_m:.1f}, {y_m:.1f}) m lies outside the geofence; "
            "the UAV must stay inside it"
        )


def _trace_track(scenario: Scenario, frame: LocalFrame) -> Track:
    # imported here so that model-only use never needs pandas' CSV machinery
    from skymule.io.traces import TraceError, positions_local, read_trace

    assert scenario.signal.trace is not None
    path = scenario.resolve_path(scenario.signal.trace)
    try:
        trace = read_trace(path)
        keys = scenario.signal.sensors_from_trace or [s.name for s in scenario.sensors]
        if len(keys) != len(scenario.sensors):
            raise ScenarioError(
                f"signal.sensors_from_trace has {len(keys)} names for "
                f"{len(scenario.sensors)} sensors; give one trace column per sensor"
            )
        columns = [trace.column_index(key) for key in keys]
    except TraceError as exc:
        raise ScenarioError(str(exc)) from None
    positions = positions_local(trace, frame.to_local)
    snr = trace.snr_db[:, columns]
    if "slot_s" in scenario.mission.model_fields_set and trace.n_samples > 1:
        # resample the recording at the requested slot length (sample-and-hold)
        slot_s = scenario.mission.slot_s
        _check_flight_slots(f"signal.trace = {str(path)!r}", trace.time_s, slot_s)
        times = flight_slot_times_s(trace.time_s, slot_s)
        index = np.searchsorted(trace.time_s, times + 1e-9, side="right") - 1
        positions, snr = positions[index], snr[index]
    return Track(position_m=positions, snr_db=snr, hold_at_end=False)


def flight_slot_times_s(time_s: np.ndarray, slot_s: float) -> np.ndarray:
    """(K,) start times [s] of the slots a recording of sample times ``time_s`` spans.

    Slot k starts at k * slot_s; the last slot starts at or before the last sample.
    """
    return np.arange(flight_slot_count(time_s, slot_s)) * slot_s


def flight_slot_count(time_s: np.ndarray, slot_s: float) -> int:
    """How many slots :func:`flight_slot_times_s` gives, computed without building them."""
    return int(np.floor(time_s[-1] / slot_s + 1e-9)) + 1


def _check_flight_slots(what: str, time_s: np.ndarray, slot_s: float) -> None:
    """Refuse a recording that spans more than MAX_SLOTS slots, before any slot is built."""
    span = float(time_s[-1]) / slot_s
    if not np.isfinite(span) or span + 1 > MAX_SLOTS:
        raise ScenarioError(
            f"{what} lasts {time_s[-1]:g} s: {span + 1:,.0f} slots of {slot_s:g} s; at most "
            f"{MAX_SLOTS:,} are allowed"
        )


def resample_positions(time_s: np.ndarray, positions_m: np.ndarray, slot_s: float) -> np.ndarray:
    """(K, 3) positions [m] at the slots' start times, linear in time between recorded samples.

    A recorded flight's positions over time, at the slots of the mission (whatever the
    recording's own sample rate: 1-s AADM polls, a 10-Hz GPS log, a gap of several seconds).
    """
    times = flight_slot_times_s(time_s, slot_s)
    return np.column_stack([np.interp(times, time_s, positions_m[:, axis]) for axis in range(3)])


def _flight_track(
    scenario: Scenario, frame: LocalFrame, source: SignalSource, fence: Polygon | None
) -> Track:
    """The recorded flight of ``trajectory.flight``, resampled to the slots, under ``source``."""
    from skymule.io.traces import TraceError, positions_local, read_trace

    assert scenario.trajectory.flight is not None
    path = scenario.resolve_path(scenario.trajectory.flight)
    try:
        trace = read_trace(path)
    except TraceError as exc:
        raise ScenarioError(f"trajectory.flight: {exc}") from None
    # counted before the slot times are built: a 1e8-s log must not allocate first
    _check_flight_slots(f"trajectory.flight = {str(path)!r}", trace.time_s, scenario.mission.slot_s)
    recorded = positions_local(trace, frame.to_local)
    _check_inside(fence, recorded, "trajectory.flight")  # like waypoints (issue 32)
    positions = resample_positions(trace.time_s, recorded, scenario.mission.slot_s)
    return Track(position_m=positions, snr_db=source.snr_db(positions), hold_at_end=False)


def mission_faults(
    scenario: Scenario, n_slots: int, names: tuple[str, ...], slot_s: float
) -> FaultDraws | None:
    """The scenario's fault draws for one mission, or None when nothing is faulty (so a
    fault-free mission takes exactly the fault-free path of every engine)."""
    if not scenario.faults:
        return None
    try:
        draws = draw_faults(scenario.faults, n_slots, names, slot_s, fault_rng(scenario.seed))
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    return None if draws.is_empty else draws


def build_mission(scenario: Scenario) -> Mission:
    """Resolve a scenario into a :class:`Mission` (raises ScenarioError on user mistakes)."""
    if scenario.uavs:
        # one Mission is one UAV: a fleet is built per UAV by skymule.sim.fleet.build_fleet
        raise ScenarioError(
            f"scenario {scenario.name!r} has [[uavs]] (several UAVs): this command runs one "
            "UAV; use skymule run / compare / bound, or skymule.sim.fleet.build_fleet"
        )
    frame = LocalFrame(scenario.site.origin.lat, scenario.site.origin.lon)
    base_dir = Path(scenario.base_dir)
    fence = scenario_fence(scenario, frame)  # site.geofence, or a .plan's inclusion fence
    sensor_m = sensor_positions_m(scenario.sensors, frame)
    rate_table = resolve_rate_table(scenario.radio.rate_table, base_dir)
    slot_s = scenario.mission.slot_s
    buffers_bit = np.array([s.buffer_mbit for s in scenario.sensors], float) * BITS_PER_MBIT
    names = tuple(s.name for s in scenario.sensors)

    source: SignalSource | None = None
    track: Track | None = None
    if scenario.signal.source == "trace":
        if scenario.trajectory.flight is not None:
            raise ScenarioError(
                "trajectory.flight flies a recorded path under a signal source that gives the "
                "SNR anywhere; signal.source = 'trace' replays its own trace's path: use "
                "source = 'radiomap' with traces = [...] to fly it under another flight's "
                "measurements"
            )
        if scenario.trajectory.mode != "fixed":
            raise ScenarioError(
                "signal.source = 'trace' replays a recorded path: it needs trajectory.mode = "
                "'fixed' (an autonomous UAV goes where the trace never went)"
            )
        track = _trace_track(scenario, frame)
        duration_s = scenario.mission.duration_s
        n_slots = track.n_samples if duration_s is None else _n_slots(duration_s, slot_s)
    else:
        missing = [s.name for s in scenario.sensors if not s.has_position]
        if missing:
            raise ScenarioError(
                f"sensors {', '.join(missing)}: a model signal source needs a position "
                "(lat/lon or x_m/y_m)"
            )
        duration_s = scenario.mission.duration_s
        if duration_s is None and scenario.trajectory.flight is None:
            raise ScenarioError(
                f"mission.duration_s is required with signal.source = "
                f"{scenario.signal.source!r} (or fly a recorded trajectory.flight)"
            )
        source = signal_source(scenario, frame, sensor_m, fence)
        if scenario.trajectory.flight is not None:
            track = _flight_track(scenario, frame, source, fence)
            n_slots = track.n_samples if duration_s is None else _n_slots(duration_s, slot_s)
        else:
            assert duration_s is not None
            n_slots = _n_slots(duration_s, slot_s)
        if scenario.trajectory.mode == "fixed" and track is None:
            waypoints = _waypoints(scenario, frame)
            _check_inside(fence, waypoints, "trajectory.waypoints")
            _check_path_samples(waypoints, scenario.trajectory.speed_mps, slot_s)
            samples = sample_path(waypoints, scenario.trajectory.speed_mps, slot_s)
            track = Track(position_m=samples, snr_db=source.snr_db(samples), hold_at_end=True)

    trajectory = scenario.trajectory
    autonomous = trajectory.mode == "autonomous"
    home = home_xy(scenario, frame)
    if autonomous:
        check_home_inside(fence, home)
    mission = Mission(
        scenario=scenario,
        frame=frame,
        fence=fence,
        sensor_names=names,
        sensor_m=sensor_m,
        buffers_bit=buffers_bit,
        slot_s=slot_s,
        n_slots=n_slots,
        rate_table=rate_table,
        bandwidth_hz=scenario.radio.bandwidth_hz,
        source=source,
        track=track,
        fading_db=mission_fading_db(scenario, n_slots, len(names)),
        mode=trajectory.mode,
        home_m=home,
        hover_points_m=hover_points(fence_or_box(fence) if autonomous else fence, sensor_m),
        visit_radius_m=trajectory.visit_radius_m,
        altitude_m=trajectory.altitude_m,
        max_speed_mps=trajectory.max_speed_mps,
        return_home=trajectory.return_home,
        navigator=Navigator(fence_or_box(fence)) if autonomous else None,
        aadm_window_s=scenario.mission.aadm_window_s,
        faults=mission_faults(scenario, n_slots, names, slot_s),
    )
    if autonomous:
        check_duration(mission)
    return mission


def mission_from_track(
    track: Track,
    buffers_mbit: list[float] | np.ndarray,
    *,
    n_slots: int,
    slot_s: float = 1.0,
    sensor_names: tuple[str, ...] | None = None,
    bandwidth_hz: float = 1.4e6,
    rate_table: str = "aadm-lte-cqi",
    policy: str = "hgad",
    hover_threshold: float = HOVER_THRESHOLD,
    max_hover_s: float = MAX_HOVER_S,
) -> Mission:
    """A fixed-trajectory mission straight from a track (no scenario file, no geodesy).

    Handy for experiments and tests: the track's SNR is what the UAV observes.
    """
    n_sensors = track.snr_db.shape[1]
    names = sensor_names or tuple(f"S{i + 1}" for i in range(n_sensors))
    scenario = Scenario.model_validate(
        {
            "name": "track",
            "mission": {"duration_s": n_slots * slot_s, "slot_s": slot_s},
            "sensors": [
                {"name": n, "buffer_mbit": float(b)}
                for n, b in zip(names, buffers_mbit, strict=True)
            ],
            "radio": {"bandwidth_hz": bandwidth_hz, "rate_table": rate_table},
            "policy": {
                "name": policy,
                "hover_threshold": hover_threshold,
                "max_hover_s": max_hover_s,
            },
        }
    )
    return Mission(
        scenario=scenario,
        frame=LocalFrame(scenario.site.origin.lat, scenario.site.origin.lon),
        fence=None,
        sensor_names=names,
        sensor_m=np.full((n_sensors, 3), np.nan),
        buffers_bit=np.asarray(buffers_mbit, float) * BITS_PER_MBIT,
        slot_s=slot_s,
        n_slots=n_slots,
        rate_table=resolve_rate_table(rate_table),
        bandwidth_hz=bandwidth_hz,
        source=None,
        track=track,
    )

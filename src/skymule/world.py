"""From a validated scenario to the SI arrays the engine runs on.

:func:`build_mission` resolves everything a scenario refers to (site frame, geofence, sensor
positions, rate table, signal source, fixed path or recorded trace) and checks what needs
geometry to check (waypoints inside the geofence, trace columns present). Everything that
comes out is in metres, seconds, bits and dB.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from shapely.geometry import Polygon

from skymule.aadm.plan import is_plan, plan_waypoints_m, scenario_fence
from skymule.errors import ScenarioError, SkymuleError
from skymule.flight.paths import Track, path_length_m, read_waypoints_csv, sample_path
from skymule.geo import LocalFrame, covers, sensor_positions_m
from skymule.radio.channel import mission_fading_db, signal_source
from skymule.radio.rates import RateTable, rate_bps, resolve_rate_table
from skymule.radio.sources import SignalSource
from skymule.scenario import Scenario

BITS_PER_MBIT = 1e6


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

    @property
    def n_sensors(self) -> int:
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
    if is_plan(spec):  # a QGroundControl .plan (skymule.aadm.plan)
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
        times = np.arange(0.0, trace.time_s[-1] + 1e-9, slot_s)
        index = np.searchsorted(trace.time_s, times + 1e-9, side="right") - 1
        positions, snr = positions[index], snr[index]
    return Track(position_m=positions, snr_db=snr, hold_at_end=False)


def build_mission(scenario: Scenario) -> Mission:
    """Resolve a scenario into a :class:`Mission` (raises ScenarioError on user mistakes)."""
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
        if scenario.mission.duration_s is None:
            raise ScenarioError("mission.duration_s is required with signal.source = 'model'")
        n_slots = _n_slots(scenario.mission.duration_s, slot_s)
        source = signal_source(scenario, frame, sensor_m, fence)
        if scenario.trajectory.mode == "fixed":
            waypoints = _waypoints(scenario, frame)
            _check_inside(fence, waypoints, "trajectory.waypoints")
            _check_path_samples(waypoints, scenario.trajectory.speed_mps, slot_s)
            samples = sample_path(waypoints, scenario.trajectory.speed_mps, slot_s)
            track = Track(position_m=samples, snr_db=source.snr_db(samples), hold_at_end=True)

    return Mission(
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
    )


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
    hover_threshold: float = 1.0,
    max_hover_s: float = 60.0,
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

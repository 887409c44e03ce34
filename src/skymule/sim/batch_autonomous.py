"""The batched autonomous engine: many Greedy or HGAD autonomous missions at once.

:func:`run_tours` loops over slots only; every step is a numpy operation over the B missions
of a batch, and it applies the same rules as the reference autonomous engine
(:mod:`skymule.sim.autonomous` with the tours of :mod:`skymule.policies.autonomous`), value
for value (the test suite compares every log field). Every slot t (``docs/contract.md``):

1. SNR and rates at each UAV's position r_t (:class:`~skymule.sim.batch_signal.BatchSignal`:
   one path-loss evaluation per shared model, per-slot fading added);
2. the tours decide (:mod:`skymule.sim.batch_tours`): Greedy serves argmax SNR, HGAD the best
   rate en route or its hover target, through :mod:`skymule.sim.contract`; each names a goal;
3. the served sensor delivers min(R dt, Q) bits (nothing once the download window closed);
4. the UAV moves at most ``max_step_m`` along the in-fence shortest path toward the legal goal
   (:meth:`~skymule.flight.navigation.Navigator.steps`: vectorised shapely ``covers`` calls
   over all missions' segments, against the same prepared polygon as the scalar queries, so
   the same decisions); with ``return_home`` the goal is overridden by home where the
   reference would override it (:class:`~skymule.sim.batch_home.HomeDeadline`, which asks for
   the distance home only where a bound cannot decide).

Missions of one batch share the geofence (one :class:`Navigator`; missions built separately
on the same fence are grouped by its geometry) and run one policy; missions with fewer sensors
are padded (no data, no hover point: never chosen, dropped from the logs).
:func:`run_autonomous_batch` (logs) and :func:`summarize_autonomous_batch` (the sweep path:
``metrics.summarize`` rows straight from the batch arrays) group and batch them. Scope
(:func:`batchable`): fault-free autonomous missions under ``greedy`` or ``hgad`` (per-slot
fading included); missions with faults and other policies run through the reference engine
(:func:`skymule.sim.run.run_mission`). The slot contract these rules implement is
``docs/contract.md``; speed and what falls back: ``docs/speed-notes.md``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.metrics import Flights, summaries, summary_dicts
from skymule.policies.autonomous import Priority
from skymule.scenario import PolicySpec
from skymule.sim import batch_paths, compiled, contract
from skymule.sim.autonomous import legal_goals
from skymule.sim.batch import Engine
from skymule.sim.batch_home import HomeDeadline
from skymule.sim.batch_paths import Paths
from skymule.sim.batch_signal import BatchSignal
from skymule.sim.batch_stack import batched_params, in_batches, mission_geometry
from skymule.sim.batch_tours import GreedyTours, HGADTours, TourGeometry
from skymule.sim.contract import NO_SENSOR
from skymule.sim.engine import log_fields
from skymule.sim.log import MissionLog
from skymule.world import Mission


@dataclass(frozen=True)
class TourParams:
    """Per-mission policy parameters of the batched tours.

    Attributes:
        hgad: True for HGAD (Alg. 2), False for Greedy (Alg. 1).
        max_hover_s: HGAD longest hover [s].
        priority: HGAD tour order (``"initial"``: planned by initial buffer; ``"remaining"``).
    """

    hgad: bool
    max_hover_s: float = 60.0
    priority: Priority = "initial"


AUTONOMOUS_POLICIES: dict[str, Callable[[PolicySpec], TourParams]] = {
    "greedy": lambda spec: TourParams(hgad=False),
    "hgad": lambda spec: TourParams(True, spec.param("max_hover_s")),
}
"""Policies with a batched autonomous engine: name -> parameters from ``[policy]``."""


def batchable(mission: Mission, spec: PolicySpec) -> bool:
    """True if autonomous ``mission`` under ``spec`` can run in the batched autonomous engine:
    Greedy or HGAD, no faults."""
    return (
        mission.mode == "autonomous"
        and mission.faults is None
        and mission.source is not None
        and mission.navigator is not None
        and mission.home_m is not None
        and mission.hover_points_m is not None
        and spec.name in AUTONOMOUS_POLICIES
    )


@dataclass(frozen=True)
class TourResult:
    """What happened in B missions of one batch, slot by slot (T = max n_slots).

    Input mission b is row ``row[b]`` (rows run longest mission first); only the row's first
    ``n_slots`` slots happened (padding: NO_SENSOR, 0 bits, not hovering, the end position).

    Attributes:
        row: (B,) the row of each input mission.
        n_slots: (B,) slots each mission ran.
        position_m: (B, T + 1, 2) UAV position at the start of each slot, then the end [m].
        served: (B, T) served sensor, or NO_SENSOR.
        downloaded_bit: (B, T) bits downloaded in each slot.
        hovering: (B, T) True where the UAV stayed put by the policy's choice.
        target: (B, T) sensor the tour headed for, or NO_SENSOR.
        left_bit: (B, N) buffers after the last slot [bit].
        snr_db: (B, T, N) SNR observed [dB], or None (``keep_logs=False``).
        rate_bps: (B, T, N) rates [bit/s], or None.
        remaining_bit: (B, T, N) buffers after each slot's download [bit], or None.
    """

    n_slots: np.ndarray
    position_m: np.ndarray
    served: np.ndarray
    downloaded_bit: np.ndarray
    hovering: np.ndarray
    target: np.ndarray
    left_bit: np.ndarray
    snr_db: np.ndarray | None
    rate_bps: np.ndarray | None
    remaining_bit: np.ndarray | None
    row: np.ndarray


def padded(values: Sequence[np.ndarray], n_sensors: int, fill: float) -> np.ndarray:
    """(N, B, ...) per-sensor arrays of B missions, missions with fewer sensors padded with
    ``fill``: padded sensors have no data and no hover point, so no tour or choice ever
    picks them, and the logs drop them."""
    first = np.asarray(values[0], float)
    out = np.full((n_sensors, len(values), *first.shape[1:]), fill)
    for b, value in enumerate(values):
        out[: len(value), b] = value
    return out


def _geometry(
    missions: Sequence[Mission], paths: Paths
) -> tuple[TourGeometry, np.ndarray, Any, Any]:
    """The tours' geometry, the legal goals (N + 1, B, 2) (hover points, then home) and the
    sights of the legal goals and of the (raw) homes."""
    nav = missions[0].navigator
    assert nav is not None
    home = np.array([m.home_m for m in missions], float).reshape(-1, 2)
    n_sensors = max(m.n_sensors for m in missions)
    hover = padded([np.asarray(m.hover_points_m, float) for m in missions], n_sensors, np.nan)
    known = np.all(np.isfinite(hover), axis=2)
    # unknown hover points are never goals; home stands in for them in the sight tables
    places = np.where(known[..., None], hover, home[None])
    # the legal goal of every hover point and home: kept where the fence covers it, else the
    # nearest fence point
    raw = np.concatenate([places, home[None]], axis=0)
    flat = legal_goals(nav, raw.reshape(-1, 2))
    legal = flat.reshape(raw.shape)
    # sights of the legal goals; the raw hover points and homes are almost always the same
    # points, computed again only where legal_goal moved them
    vis, dist = paths.sights(flat)
    legal_sight = (vis.reshape(*legal.shape[:-1], -1), dist.reshape(*legal.shape[:-1], -1))
    raw_sight = (legal_sight[0].copy(), legal_sight[1].copy())
    moved = np.any(raw != legal, axis=2)
    if moved.any():
        raw_sight[0][moved], raw_sight[1][moved] = paths.sights(raw[moved])
    hover_sight = (raw_sight[0][:-1], raw_sight[1][:-1])
    geometry = TourGeometry(paths, hover, known, home, hover_sight)
    return geometry, legal, legal_sight, (raw_sight[0][-1], raw_sight[1][-1])


def _stack(missions: Sequence[Mission]) -> None:
    """Check that ``missions`` can share a batch (one fence)."""
    if not missions:
        raise ValueError("a batch needs at least one mission")
    for mission in missions:
        if mission.mode != "autonomous" or mission.navigator is None or mission.source is None:
            raise SkymuleError("the batched autonomous engine needs autonomous missions")
        if mission.faults is not None:
            raise SkymuleError(
                "the batched autonomous engine does not apply faults: run such missions with "
                "skymule.sim.run.run_mission (the reference engines)"
            )
    fences = {m.navigator.fence_key for m in missions if m.navigator is not None}
    if len(fences) != 1:
        raise ValueError("a batch needs one geofence")


def run_tours(
    missions: Sequence[Mission],
    params: Sequence[TourParams],
    keep_logs: bool = True,
    engine: Engine = "auto",
) -> TourResult:
    """Run B autonomous missions (one fence, all Greedy or all HGAD; sensor counts may differ).

    ``keep_logs=False`` skips the (B, T, N) SNR, rate and buffer logs (summaries do not need
    them). ``engine``: ``"numpy"`` (the reference batched path), ``"compiled"`` (the path
    queries' arithmetic compiled with numba, :mod:`skymule.sim.batch_paths`; the same
    result, value for value) or ``"auto"`` (compiled when numba is installed).
    """
    _stack(missions)
    nav = missions[0].navigator
    assert nav is not None
    paths = batch_paths.path_queries(nav, engine)
    if len({p.hgad for p in params}) != 1 or len(params) != len(missions):
        raise ValueError("a batch runs one policy: one TourParams per mission, all Greedy or HGAD")
    lengths = np.array([m.n_slots for m in missions], np.int64)
    order = np.argsort(-lengths, kind="stable")  # active missions are a prefix of the columns
    sorted_missions = [missions[i] for i in order]
    result = _slot_loop(sorted_missions, [params[i] for i in order], keep_logs, paths)
    return replace(result, row=np.argsort(order))


def _slot_loop(
    missions: Sequence[Mission],
    params: Sequence[TourParams],
    keep_logs: bool,
    paths: Paths,
) -> TourResult:
    """:func:`run_tours` on missions sorted by length, longest first."""
    n_missions, n_sensors = len(missions), max(m.n_sensors for m in missions)
    geometry, legal, legal_sight, home_sight = _geometry(missions, paths)
    nav = geometry.navigator
    n_slots = np.array([m.n_slots for m in missions], np.int64)
    slot_s = np.array([m.slot_s for m in missions], float)
    step_m = np.array([m.max_step_m for m in missions], float)
    window = np.array([m.n_slots if m.window_slots is None else m.window_slots for m in missions])
    buffers = padded([m.buffers_bit for m in missions], n_sensors, 0.0)
    signal = BatchSignal(missions, n_sensors)
    tours: GreedyTours | HGADTours
    if params[0].hgad:
        tours = HGADTours(
            geometry,
            signal.peak_rate_bps(geometry.hover_m),
            buffers,
            slot_s,
            np.array([p.max_hover_s for p in params], float),
            np.array([p.priority == "initial" for p in params], bool),
        )
    else:
        tours = GreedyTours(geometry, np.array([m.visit_radius_m for m in missions], float))

    t_max = int(n_slots.max())
    position = geometry.home_m.copy()
    remaining = buffers.copy()
    deadline = HomeDeadline(nav, missions, geometry.home_m, home_sight)
    # where the policy's home (made legal) is the home itself, flying home is the override's move
    home_is_legal = np.all(legal[n_sensors] == geometry.home_m, axis=1)
    position_log = np.empty((t_max + 1, n_missions, 2))
    served_log = np.full((t_max, n_missions), NO_SENSOR, np.int64)
    downloaded_log = np.zeros((t_max, n_missions))
    hovering_log = np.zeros((t_max, n_missions), bool)
    target_log = np.full((t_max, n_missions), NO_SENSOR, np.int64)
    shape = (t_max, n_sensors, n_missions) if keep_logs else (0, n_sensors, n_missions)
    snr_log, rate_log, remaining_log = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    n_active = (n_slots[None, :] > np.arange(t_max)[:, None]).sum(axis=1)

    for slot in range(t_max):
        active = int(n_active[slot])
        position_log[slot] = position
        here = position[:active]
        snr = signal.snr_db(here, slot)
        rate = signal.rate_bps(snr)
        left = remaining[:, :active]
        serve, goal, target = tours.act(here, np.nan_to_num(snr, nan=-np.inf), rate, left)
        sensor = np.where(slot >= window[:active], NO_SENSOR, serve)
        cols = np.flatnonzero(sensor >= 0)
        rows = sensor[cols]
        bits = np.zeros(active)
        bits[cols] = contract.served_bits(rate[rows, cols], left[rows, cols], slot_s[cols])
        left[rows, cols] -= bits[cols]
        moved = here.copy()
        # a step toward the position itself (STAY, or a UAV already at its goal) stays put
        going = np.flatnonzero(goal >= 0)
        there = legal[goal[going], going]
        going = going[(there[:, 0] != here[going, 0]) | (there[:, 1] != here[going, 1])]
        likely = deadline.likely(active)  # their step home, in the same query
        home_move = np.full((active, 2), np.nan)
        if going.size or likely.size:
            g = goal[going]
            rows = np.concatenate([going, likely])
            found = nav.steps(
                here[rows],
                np.concatenate([legal[g, going], geometry.home_m[likely]]),
                step_m[rows],
                (
                    np.concatenate([legal_sight[0][g, going], home_sight[0][likely]]),
                    np.concatenate([legal_sight[1][g, going], home_sight[1][likely]]),
                ),
                checked=False,  # positions and legal goals are in the fence by construction
            )
            moved[going] = found[: going.size]
            home_move[likely] = found[going.size :]
        overridden = (
            deadline.apply(
                slot, here, moved, (goal == n_sensors) & home_is_legal[:active], home_move
            )
            if deadline.on[:active].any()
            else np.zeros(active, bool)
        )
        served_log[slot, :active] = sensor
        downloaded_log[slot, :active] = bits
        hovering_log[slot, :active] = (
            (moved[:, 0] == here[:, 0]) & (moved[:, 1] == here[:, 1]) & ~overridden
        )
        target_log[slot, :active] = target
        if keep_logs:
            snr_log[slot, :, :active] = snr
            rate_log[slot, :, :active] = rate
            remaining_log[slot, :, :active] = left
        position[:active] = moved
    position_log[t_max] = position

    def per_mission(log: np.ndarray) -> np.ndarray | None:
        return log.transpose(2, 0, 1) if keep_logs else None

    return TourResult(
        n_slots=n_slots,
        position_m=position_log.transpose(1, 0, 2),
        served=served_log.T,
        downloaded_bit=downloaded_log.T,
        hovering=hovering_log.T,
        target=target_log.T,
        left_bit=remaining.T,
        snr_db=per_mission(snr_log),
        rate_bps=per_mission(rate_log),
        remaining_bit=per_mission(remaining_log),
        row=np.arange(n_missions),
    )


def mission_log(result: TourResult, b: int, mission: Mission, policy: str) -> MissionLog:
    """Mission b's :class:`MissionLog`, field for field as the reference engine makes it."""
    if result.snr_db is None or result.rate_bps is None or result.remaining_bit is None:
        raise ValueError("run_tours(..., keep_logs=True) for logs")
    b = int(result.row[b])
    n, sensors = int(result.n_slots[b]), mission.n_sensors
    altitude = mission.altitude_m
    end = result.position_m[b, n]
    return MissionLog(
        **log_fields(mission, policy),
        position_m=np.hstack([result.position_m[b, :n], np.full((n, 1), altitude)]),
        end_position_m=np.array([end[0], end[1], altitude]),
        snr_db=result.snr_db[b, :n, :sensors].copy(),
        rate_bps=result.rate_bps[b, :n, :sensors].copy(),
        served=result.served[b, :n].copy(),
        downloaded_bit=result.downloaded_bit[b, :n].copy(),
        remaining_bit=result.remaining_bit[b, :n, :sensors].copy(),
        hovering=result.hovering[b, :n].copy(),
        target=result.target[b, :n].copy(),
    )


def tour_flights(result: TourResult, rows: np.ndarray, missions: Sequence[Mission]) -> Flights:
    """Rows ``rows`` of the batch, missions ``missions`` (one sensor count N), as
    :class:`~skymule.metrics.Flights`: each mission's path is its own track."""
    n_missions, n_sensors = len(rows), missions[0].n_sensors
    t_max = result.served.shape[1]
    altitude = np.array([m.altitude_m for m in missions], float)
    track = np.concatenate(
        [
            result.position_m[rows],
            np.broadcast_to(altitude[:, None, None], (n_missions, t_max + 1, 1)),
        ],
        axis=2,
    )
    n_run = result.n_slots[rows]
    home, hover, radius, window = mission_geometry(missions, n_sensors)
    return Flights(
        n_run=n_run,
        slot_s=np.array([m.slot_s for m in missions], float),
        buffers_bit=np.array([m.buffers_bit for m in missions], float).reshape(n_missions, -1),
        left_bit=result.left_bit[rows, :n_sensors],
        served=result.served[rows],
        downloaded_bit=result.downloaded_bit[rows],
        hovering=result.hovering[rows],
        track_position_m=track,
        track_samples=n_run + 1,
        track_id=np.arange(n_missions),
        sample=np.minimum(np.arange(t_max)[None, :], n_run[:, None]),
        end_sample=n_run,
        home_m=home,
        hover_points_m=hover,
        visit_radius_m=radius,
        target=result.target[rows],
        aadm_window_s=window,
    )


def tour_params(spec: PolicySpec) -> TourParams:
    """The batched tours' parameters of a ``[policy]`` section (SkymuleError if none)."""
    return batched_params(AUTONOMOUS_POLICIES, spec, "batched autonomous engine")


def _batches(
    missions: Sequence[Mission], params: Sequence[TourParams], batch_size: int
) -> Iterator[list[int]]:
    """Indices of missions that can share a batch (fence, policy), at most ``batch_size``
    each."""
    groups: dict[tuple[bytes, bool], list[int]] = {}
    for index, (mission, param) in enumerate(zip(missions, params, strict=True)):
        nav = mission.navigator
        if nav is None:
            raise SkymuleError("the batched autonomous engine needs autonomous missions")
        groups.setdefault((nav.fence_key, param.hgad), []).append(index)
    return in_batches(groups.values(), batch_size)


def _params(specs: Sequence[PolicySpec]) -> list[TourParams]:
    by_spec: dict[int, TourParams] = {}  # sweeps repeat a few spec objects many times
    for spec in specs:
        if id(spec) not in by_spec:
            by_spec[id(spec)] = tour_params(spec)
    return [by_spec[id(spec)] for spec in specs]


def run_autonomous_batch(
    missions: Sequence[Mission],
    specs: Sequence[PolicySpec],
    batch_size: int = 1000,
    engine: Engine = "auto",
) -> list[MissionLog]:
    """Logs of autonomous Greedy/HGAD missions (one policy spec each), in input order.

    Equal to ``[run_autonomous(m, make_policy(s)) for m, s in zip(missions, specs)]``;
    ``engine`` as in :func:`run_tours`.
    """
    params = _params(specs)
    logs: list[MissionLog | None] = [None] * len(missions)
    for part in _batches(missions, params, batch_size):
        result = run_tours([missions[i] for i in part], [params[i] for i in part], True, engine)
        for b, i in enumerate(part):
            logs[i] = mission_log(result, b, missions[i], specs[i].name)
    return [log for log in logs if log is not None]


def summarize_autonomous_batch(
    missions: Sequence[Mission],
    specs: Sequence[PolicySpec],
    scenario_names: Sequence[str],
    batch_size: int = 1000,
    engine: Engine = "auto",
) -> list[dict[str, Any]]:
    """``metrics.summarize`` dictionaries of autonomous Greedy/HGAD missions, in input order,
    straight from the batch arrays (no per-mission log); ``engine`` as in :func:`run_tours`.
    The compiled engine reduces the arrays compiled too (``compiled_summaries.flights_summaries``,
    equal to ``metrics.summaries``, which the numpy engine keeps)."""
    from skymule.sim.compiled_summaries import flights_summaries

    summarize = flights_summaries if engine != "numpy" and compiled.available() else summaries
    params = _params(specs)
    rows: list[dict[str, Any] | None] = [None] * len(missions)
    for part in _batches(missions, params, batch_size):
        result = run_tours([missions[i] for i in part], [params[i] for i in part], False, engine)
        by_row = np.array(part)[np.argsort(result.row)]  # the input mission of each row
        sizes = np.array([missions[i].n_sensors for i in by_row])
        for n_sensors in np.unique(sizes):  # metrics per sensor count: no padded sensors
            chosen = np.flatnonzero(sizes == n_sensors)
            inputs = [int(i) for i in by_row[chosen]]
            dicts = summary_dicts(
                summarize(tour_flights(result, chosen, [missions[i] for i in inputs])),
                [missions[i].sensor_names for i in inputs],
                [specs[i].name for i in inputs],
                [scenario_names[i] for i in inputs],
            )
            for i, row in zip(inputs, dicts, strict=True):
                rows[i] = row
    return [row for row in rows if row is not None]

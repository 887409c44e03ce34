"""Running a sweep: plan, skip what is done, run chunks on an executor, store, summarise.

The sweep process sends each worker the sweep plan once (:class:`SweepPlan`) and each chunk
as a range of run positions, with the indices of any missions of the range already stored:
nothing per mission is planned, pickled or held in the sweep process. A worker plans its
range, resolves and validates each mission once, builds each geometry once per chunk
(missions that differ only in buffers, policy, name or, without shadowing, seed share one
built track and batch together) and, on this machine, writes its own part (a remote Dask
worker returns the part's bytes). Chunks are at most ``chunk_size`` missions and within a
memory budget. ``results.parquet`` and ``summary.csv`` are then streamed from the parts
(:func:`skymule.experiments.store.consolidate`).

Every mission runs through the engine of its trajectory mode, batched with the missions it can
share a batch with (:func:`skymule.sim.run.summarize_missions`: mode, sensor count, geofence),
under any policy: the built-in ones batched (Greedy and HGAD on fixed paths inside the
compiled loop, no per-slot log), per-mission ones one instance per mission. The row is
``metrics.summarize`` of the mission's log, value for value, as ``skymule run`` gives.
"""

from __future__ import annotations

import json
import math
import sys
import tempfile
import time
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, wait
from dataclasses import dataclass, replace
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError
from skymule.experiments import store
from skymule.experiments.executors import (
    EXECUTORS,
    executor_slots,
    open_executor,
    sees_local_files,
    share,
    ship_modules,
)
from skymule.experiments.fields import column
from skymule.experiments.sweep import (
    Axis,
    Expansion,
    PlannedMission,
    SweepPlan,
    SweepSpec,
    expansion,
    sweep_plan,
)
from skymule.io import atomic
from skymule.metrics.summary import per_sensor_column
from skymule.radio.channel import mission_fading_db
from skymule.units import BITS_PER_MBIT
from skymule.world import Mission, mission_faults

if TYPE_CHECKING:
    from skymule.scenario import Scenario

WORKER_MODULES = (
    "skymule.experiments.run",
    "skymule.scenario",
    "skymule.world",
    "skymule.sim.run",
    "skymule.sim.fixed",
    "skymule.policies",
    "pyarrow.parquet",
)
"""What a local worker imports as it starts (while the sweep process plans the first chunk)."""

Task = tuple[int, str, dict[str, Any], dict[str, Any]]
"""(mission index, mission id, axis values, resolved scenario dict)."""


@dataclass(frozen=True)
class SweepOutcome:
    """A finished sweep: its folder, the summary (per policy and swept value), what it ran."""

    folder: Path
    summary: pd.DataFrame
    n_missions: int
    n_run: int
    seconds: float

    @property
    def results(self) -> pd.DataFrame:
        """Every row of ``results.parquet`` in memory (for sweeps that fit; a large one is read
        a row group at a time with ``pyarrow.parquet.ParquetFile``)."""
        return pd.read_parquet(self.folder / store.RESULTS)


def _flat_summary(summary: dict[str, Any]) -> dict[str, Any]:
    row: dict[str, Any] = {}
    for key, value in summary.items():
        if isinstance(value, dict):
            row.update({per_sensor_column(key, name): v for name, v in value.items()})
        elif isinstance(value, list | tuple):
            row[key] = ",".join(str(v) for v in value)
        else:
            row[key] = value
    return row


def _param_value(value: Any) -> Any:
    return json.dumps(value) if isinstance(value, list | dict) else value


def _needs_seed(scenario: Scenario) -> bool:
    """True if the scenario's seed changes the built mission (shadowing draws a field).

    Fading also follows the seed but is redrawn per mission (:func:`_per_mission`), so missions
    that differ only in their seed share one built track and batch together.
    """
    return scenario.signal.source == "model" and scenario.radio.shadowing_std_db > 0


def _geometry_key(data: dict[str, Any], scenario: Scenario) -> str:
    """Missions differing only in buffers, policy, name (and seed) share one built Mission."""
    sensors = [{k: v for k, v in s.items() if k != "buffer_mbit"} for s in data["sensors"]]
    skip = (
        ("policy", "name", "sensors")
        if _needs_seed(scenario)
        else ("policy", "name", "sensors", "seed")
    )
    rest = {k: v for k, v in data.items() if k not in skip}
    return json.dumps([rest, sensors], sort_keys=True, default=str)


def _shares_geometry(axis: Axis) -> bool:
    """Axes that never change the built mission (the seed is handled per mission)."""
    return (
        axis.paired
        or axis.key in ("name", "seed")
        or (axis.path[0] == "sensors" and axis.path[-1] == "buffer_mbit")
    )


@dataclass(frozen=True)
class _Item:
    """One mission of a chunk, validated: position, id, axis values (columns), geometry key."""

    index: int
    mission_id: str
    params: dict[str, Any]
    scenario: Scenario
    key: Hashable


@dataclass(frozen=True)
class _Runs:
    """A chunk's missions, validated, in chunk order, as columns: what the engine and the
    rows need. ``scenarios[j]`` is mission j's scenario; its buffers are ``buffers_bit[j]``
    (the scenario's own may be those of another mission with the same structure)."""

    index: list[int]
    mission_id: list[str]
    params: dict[str, list[Any]]  # result columns of the axis values
    scenarios: list[Scenario]
    buffers_bit: list[np.ndarray]  # (N,) each
    keys: list[Hashable]  # missions with one key share one built mission


def _buffers_bit(scenario: Scenario) -> np.ndarray:
    return np.array([s.buffer_mbit for s in scenario.sensors], float) * BITS_PER_MBIT


def _per_mission(built: Mission, scenario: Scenario, buffers: np.ndarray | None = None) -> Mission:
    """The shared built mission with this mission's scenario, buffers and fading."""
    buffers = _buffers_bit(scenario) if buffers is None else buffers
    fading = built.fading_db
    if fading is not None:  # fading is on for every mission of this geometry: redraw it
        fading = mission_fading_db(scenario, built.n_slots, len(buffers))
    # faults follow the seed: drawn for this mission (None without [[faults]])
    faults = mission_faults(scenario, built.n_slots, built.sensor_names, built.slot_s)
    return built.for_run(scenario, buffers, fading, faults)


def run_chunk(tasks: Sequence[Task], base_dir: str) -> pd.DataFrame:
    """Run a chunk of resolved missions; one row per mission, in task order."""
    from skymule.scenario import scenario_from_dict

    items = []
    for index, mission_id, params, data in tasks:
        scenario = scenario_from_dict(data, f"mission {mission_id}", Path(base_dir))
        items.append(_Item(index, mission_id, params, scenario, _geometry_key(data, scenario)))
    return _run_items(items)


def run_planned(
    resolve: Expansion, planned: Sequence[PlannedMission], sweep: bytes | None = None
) -> pd.DataFrame:
    """Run a chunk of planned missions (in a worker): each is resolved and validated here once.

    The worker gets the base scenario once (``resolve``) and each mission as its axis values;
    ``sweep`` (the plan's id prefix) lets it reuse the missions it built for earlier chunks
    of the same sweep. Missions that differ only in their buffers, seed and name share one
    validated scenario (:func:`_chunk_runs`); a value those checks do not pass sends the chunk
    through the full validation of each mission, which names the first bad mission as it
    always did.
    """
    runs = _chunk_runs(resolve, planned)
    identity = None if sweep is None else (sweep, resolve.base_dir)
    return _run(runs if runs is not None else _validated_runs(resolve, planned), identity)


def run_range(
    plan: SweepPlan, start: int, stop: int, skip: np.ndarray | None, out: str | None
) -> tuple[int, bytes | None]:
    """Run the missions at run positions ``start`` to ``stop`` of ``plan`` (in a worker).

    ``skip``: mission indices already stored (resumes). With ``out`` (a worker that sees the
    sweep folder) the worker writes its own part and returns ``(count, None)``; without, it
    returns the part's bytes for the sweep process to store.
    """
    missions: Iterable[PlannedMission] = plan.missions(start, stop)
    if skip is not None and skip.size:
        stored = set(skip.tolist())
        missions = [m for m in missions if m.index not in stored]
    frame = run_planned(plan.resolve, list(missions), plan.prefix)
    if out is None:
        return len(frame), store.part_bytes(frame)
    store.write_part(Path(out), frame)
    return len(frame), None


def _validated_runs(resolve: Expansion, planned: Sequence[PlannedMission]) -> _Runs:
    """Each mission resolved and validated in full (its one-line error names it)."""
    geometric = [i for i, axis in enumerate(resolve.axes) if not _shares_geometry(axis)]
    scenarios: list[Scenario] = []
    keys: list[Hashable] = []
    for mission in planned:
        scenario = resolve.validate(mission)
        key: tuple[Any, ...] = tuple(repr(mission.values[i]) for i in geometric)
        if _needs_seed(scenario):
            key = (*key, scenario.seed)
        scenarios.append(scenario)
        keys.append(key)
    return _Runs(
        [m.index for m in planned],
        [m.mission_id for m in planned],
        param_columns(resolve, [m.values for m in planned]),
        scenarios,
        [_buffers_bit(s) for s in scenarios],
        keys,
    )


def _array_field(axis: Axis) -> str | None:
    """The field an axis sets that changes nothing a mission is built or validated from but
    itself: a sensor's ``buffer_mbit``, the ``seed`` or the ``name`` (None: another field)."""
    if axis.key in ("seed", "name"):
        return axis.key
    path = axis.path
    if len(path) == 3 and path[0] == "sensors" and path[2] == "buffer_mbit":
        return "buffer_mbit"
    return None


def _field_info(field: str) -> Any:
    from skymule.scenario import Scenario, SensorSpec

    return (SensorSpec if field == "buffer_mbit" else Scenario).model_fields[field]


def allowed_values(values: Sequence[Any], field: str) -> bool:
    """True when every one of ``values`` passes the scenario's check of ``field``
    (``buffer_mbit``, ``seed`` or ``name``): its strict type, finite, and its bounds, read
    from the scenario model itself; checked over an array at once. False may also mean
    "not sure" (a huge integer): the caller then validates each mission in full."""
    import annotated_types as at

    info = _field_info(field)
    types = {type(v) for v in values}
    if info.annotation is str:
        return types <= {str}
    if not types <= ({int} if info.annotation is int else {int, float}):
        return False  # bool, str, numpy scalars, lists: the full check says what is wrong
    try:
        array = np.asarray(values, float)
    except OverflowError:
        return False
    ok = np.isfinite(array)
    for bound in info.metadata:
        if isinstance(bound, at.Ge):
            ok &= array >= bound.ge
        elif isinstance(bound, at.Gt):
            ok &= array > bound.gt
        elif isinstance(bound, at.Le):
            ok &= array <= bound.le
        elif isinstance(bound, at.Lt):
            ok &= array < bound.lt
        else:
            return False
    return bool(ok.all())


def _chunk_runs(resolve: Expansion, planned: Sequence[PlannedMission]) -> _Runs | None:
    """The chunk's missions with one validated scenario per structure (the values of every
    axis but the buffer, seed and name axes) and those axes' values checked over arrays,
    each once; None when a value fails a check (the full validation then names it)."""
    fields = [_array_field(axis) for axis in resolve.axes]
    structural = [i for i, field in enumerate(fields) if field is None]
    values = [m.values for m in planned]
    for i, field in enumerate(fields):
        if field is None:
            continue
        column_ = [v[i] for v in values]
        if resolve.counts[i] is not None and resolve.axes[i].dist is not None:
            column_ = [x for drawn in column_ for x in drawn]
        if not allowed_values(column_, field):
            return None
    groups: dict[tuple[str, ...], list[int]] = {}
    for j, v in enumerate(values):
        groups.setdefault(tuple(repr(v[i]) for i in structural), []).append(j)
    geometric = [i for i in structural if not _shares_geometry(resolve.axes[i])]
    scenarios: list[Any] = [None] * len(planned)
    buffers: list[Any] = [None] * len(planned)
    keys: list[Hashable] = [None] * len(planned)
    for members in groups.values():
        try:
            structure = resolve.validate(planned[members[0]])
        except SkymuleError:
            return None
        group = _group_values(resolve, fields, structure, [values[j] for j in members])
        if group is None:
            return None
        bits, seeds, names = group
        key = tuple(repr(values[members[0]][i]) for i in geometric)
        by_seed = _needs_seed(structure)
        for row, j in enumerate(members):
            seed, name = seeds[row], names[row]
            scenario = structure
            if seed != structure.seed or name != structure.name:
                scenario = structure.model_copy(update={"seed": seed, "name": name})
            scenarios[j] = scenario
            buffers[j] = bits[row]
            keys[j] = (*key, seed) if by_seed else key
    return _Runs(
        [m.index for m in planned],
        [m.mission_id for m in planned],
        param_columns(resolve, values),
        scenarios,
        buffers,
        keys,
    )


def _group_values(
    resolve: Expansion,
    fields: Sequence[str | None],
    structure: Scenario,
    values: Sequence[Sequence[Any]],
) -> tuple[np.ndarray, list[int], list[str]] | None:
    """(M, N) buffers [bit], seeds and names of missions sharing ``structure``: its own
    values with the buffer, seed and name axes applied in axis order (None: an axis does not
    fit its sensors; the full validation says how)."""
    n = len(structure.sensors)
    mbit = np.repeat(
        np.array([[s.buffer_mbit for s in structure.sensors]], float), len(values), axis=0
    )
    seeds = [structure.seed] * len(values)
    names = [structure.name] * len(values)
    for i, field in enumerate(fields):
        if field is None:
            continue
        column_ = [v[i] for v in values]
        if field == "seed":
            seeds = column_
        elif field == "name":
            names = column_
        else:
            sensor = resolve.axes[i].path[1]
            if sensor == "*":
                if resolve.counts[i] != n:
                    return None
                drawn = resolve.axes[i].dist is not None
                mbit[:] = np.array(column_, float) if drawn else np.array(column_, float)[:, None]
            elif isinstance(sensor, int) and sensor < n:
                mbit[:, sensor] = column_
            else:
                return None
    return mbit * BITS_PER_MBIT, seeds, names


def param_columns(resolve: Expansion, values: Sequence[Sequence[Any]]) -> dict[str, list[Any]]:
    """The result columns of the axis values of missions (``sensors[*]`` axes get one column
    per sensor; lists and tables as JSON): :meth:`Expansion.params`, column by column."""
    columns: dict[str, list[Any]] = {}
    for i, (axis, count) in enumerate(zip(resolve.axes, resolve.counts, strict=True)):
        column_ = [v[i] for v in values]
        if count is None:
            columns[axis.key] = _param_column(column_)
        elif axis.values is not None:
            for k in range(count):
                columns[column(axis.key, k)] = _param_column(column_)
        else:
            for k in range(count):
                columns[column(axis.key, k)] = _param_column([drawn[k] for drawn in column_])
    return columns


def _param_column(values: list[Any]) -> list[Any]:
    if any(issubclass(kind, list | dict) for kind in set(map(type, values))):
        return [_param_value(v) for v in values]
    return values


def _run_items(items: Sequence[_Item]) -> pd.DataFrame:
    """Build each geometry once, run every mission through the engine in batches, summarise
    every row."""
    params = [item.params for item in items]
    names = list(dict.fromkeys(k for p in params for k in p))
    return _run(
        _Runs(
            [item.index for item in items],
            [item.mission_id for item in items],
            {k: [_param_value(p[k]) if k in p else None for p in params] for k in names},
            [item.scenario for item in items],
            [_buffers_bit(item.scenario) for item in items],
            [item.key for item in items],
        )
    )


#: Missions built by this process's last chunks, by (sweep, geometry key): the next chunk of
#: the same sweep reuses them (a build is milliseconds; a chunk is a few hundred missions).
_BUILT: OrderedDict[tuple[Hashable, Hashable], Mission] = OrderedDict()
_BUILT_KEEP = 8


def _keep_built(key: tuple[Hashable, Hashable], mission: Mission) -> None:
    _BUILT[key] = mission
    _BUILT.move_to_end(key)
    while len(_BUILT) > _BUILT_KEEP:
        _BUILT.popitem(last=False)


def _run(runs: _Runs, sweep: Hashable = None) -> pd.DataFrame:
    """Build each geometry once, run every mission through the engine in batches, one row
    per mission (written as columns). ``sweep``: what identifies the sweep, whose chunks'
    keys name the same geometries (its built missions are then kept for its next chunks)."""
    from skymule.sim.run import summarize_missions
    from skymule.world import build_mission

    built: dict[Hashable, Mission] = {}
    missions: list[Mission] = []
    for scenario, key, buffers in zip(runs.scenarios, runs.keys, runs.buffers_bit, strict=True):
        shared = built.get(key)
        if shared is None and sweep is not None:
            shared = _BUILT.get((sweep, key))
        if shared is None:
            shared = build_mission(scenario)
            if shared.track is not None:
                # the track holds the SNR; a shadowing field (tens of MB) is not kept per mission
                shared = replace(shared, source=None)
            if shared.track is not None or not _needs_seed(scenario):
                built[key] = shared
                if sweep is not None:
                    _keep_built((sweep, key), shared)
        missions.append(_per_mission(shared, scenario, buffers))
    summaries = summarize_missions(
        missions, [s.policy for s in runs.scenarios], [s.name for s in runs.scenarios]
    )
    columns: dict[str, list[Any]] = {"mission_index": runs.index, "mission_id": runs.mission_id}
    columns.update(runs.params)
    flat = _summary_columns(summaries)
    if flat is None:  # missions whose summaries differ in shape (other sensors): row by row
        rows = [_flat_summary(summary) for summary in summaries]
        flat = {k: [row.get(k) for row in rows] for k in dict.fromkeys(k for r in rows for k in r)}
    columns.update(flat)
    return pd.DataFrame(columns)


def _summary_columns(summaries: Sequence[dict[str, Any]]) -> dict[str, list[Any]] | None:
    """:func:`_flat_summary` of every summary, column by column; None when the summaries do
    not all have the same keys (and sensor names)."""
    if not summaries:
        return {}
    first = summaries[0]
    keys = first.keys()
    nested = [k for k, v in first.items() if isinstance(v, dict)]
    for summary in summaries:
        if summary.keys() != keys:
            return None
        for k in nested:
            value = summary[k]
            if not isinstance(value, dict) or value.keys() != first[k].keys():
                return None
    columns: dict[str, list[Any]] = {}
    for key in keys:
        values = [summary[key] for summary in summaries]
        if key in nested:
            for name in first[key]:
                columns[f"{key}.{name}"] = [value[name] for value in values]
            continue
        kinds = set(map(type, values))
        if any(issubclass(k, dict | list | tuple) for k in kinds):  # one test per type
            if any(issubclass(k, dict) for k in kinds):
                return None
            values = [
                ",".join(str(x) for x in v) if isinstance(v, list | tuple) else v for v in values
            ]
        columns[key] = values
    return columns


def policy_modules(spec: SweepSpec) -> list[str]:
    """The modules of the ``module:Class`` policies a sweep runs (base and ``policy.name``)."""
    from skymule.policies.registry import is_plugin

    names = [spec.base.policy.name]
    for axis in spec.discrete:
        if axis.key == "policy.name":
            names.extend(str(v) for v in axis.values or ())
    return [n.partition(":")[0] for n in names if is_plugin(n)]


#: Memory a chunk may use in a worker [byte] (its batch arrays and built tracks).
CHUNK_MEMORY_BYTES = 256 * 2**20


def mission_bytes(scenario: Scenario) -> int:
    """Estimated peak bytes one mission adds to a chunk (slots x sensors, its own track)."""
    from skymule.sim.run import batch_bytes

    duration = scenario.mission.duration_s or 3600.0
    slots = max(1, math.ceil(duration / scenario.mission.slot_s))
    sensors = max(1, len(scenario.sensors))
    per_slot = batch_bytes(1, sensors)
    if scenario.radio.fading != "none":
        per_slot += 8 * sensors
    if _needs_seed(scenario):
        per_slot += 3 * 8 * sensors  # a track of its own (SNR, rate, seen SNR) per mission
    return slots * per_slot


#: Axes that change a mission's memory, and the value that needs the most.
_WORST: dict[str, Callable[[Sequence[Any]], Any]] = {
    "mission.duration_s": lambda v: max(v[0], v[-1]) if isinstance(v, range) else max(v),
    "mission.slot_s": lambda v: min(v),
    "radio.shadowing_std_db": lambda v: max(v),
    "radio.fading": lambda v: next((f for f in v if f != "none"), v[0]),
}


def _largest_mission(spec: SweepSpec) -> Scenario:
    """The base scenario with every memory-relevant list axis at its most demanding value."""
    from skymule.scenario import scenario_from_dict

    resolve = expansion(spec)
    data = resolve.base
    for axis in spec.discrete:
        worst = _WORST.get(axis.key)
        if worst is not None and axis.values:
            data = resolve.scenario_with(data, axis, worst(axis.values))
    data = resolve.placed(data)
    try:
        return scenario_from_dict(data, spec.source, Path(spec.base.base_dir))
    except SkymuleError:  # mixed types in an axis: the missions' own checks will say so
        return spec.base


def auto_chunk_size(
    spec: SweepSpec, limit: int, n_workers: int, budget_bytes: int = CHUNK_MEMORY_BYTES
) -> int:
    """Missions per chunk: at most ``limit``, within the memory budget, >= 2 chunks per worker
    when there are several.

    A shadowing field is drawn per mission and dropped once its track is sampled, so it costs
    one field at a time (not per mission) and does not enter the per-mission estimate.
    """
    by_memory = max(1, budget_bytes // mission_bytes(_largest_mission(spec)))
    by_balance = math.ceil(len(spec) / (2 * n_workers)) if n_workers > 1 else limit
    return max(1, min(limit, by_memory, by_balance))


def _chunk_ranges(
    plan: SweepPlan, done: store.Done, size: int
) -> Iterator[tuple[int, int, np.ndarray | None]]:
    """Run-position ranges of ``size`` missions with the indices already stored in each;
    ranges wholly stored are left out. Costs a few numpy operations per range, none per
    mission."""
    total = len(plan)
    for start in range(0, total, size):
        stop = min(total, start + size)
        if not done.mask.size:
            yield start, stop, None
            continue
        indices = plan.indices(start, stop)
        stored = done.which(indices)
        if stored.all():
            continue
        yield start, stop, indices[stored] if stored.any() else None


def run_sweep(
    spec: SweepSpec,
    out: Path,
    *,
    executor: str = "process",
    workers: int | None = None,
    scheduler: str | None = None,
    chunk_size: int = 500,
    progress: bool = True,
    memory_bytes: int = CHUNK_MEMORY_BYTES,
) -> SweepOutcome:
    """Run the missions of ``spec`` not yet in ``out``, then consolidate and summarise.

    ``out`` is locked while this runs and tied to ``spec``'s sweep file; ``chunk_size`` is an
    upper bound, lowered to keep a chunk within ``memory_bytes``. Workers get the plan once
    and each chunk as a range of run positions; workers on this machine write their own
    parts, a remote Dask worker returns its part's bytes.
    """
    if chunk_size < 1:
        raise SkymuleError(f"--chunk-size {chunk_size}: allowed: an integer >= 1")
    start = time.perf_counter()
    with store.locked(out):
        store.claim(out, spec.digest, spec.source)
        # parts a killed worker or sweep was writing (temporary names): run again below
        atomic.remove_stale_temporaries(out / store.PARTS)
        found = store.scan(out, set_aside=True)
        for path in found.damaged:
            print(
                f"warning: {path} is damaged (unreadable Parquet); set aside as "
                f"{path.name}.damaged, its missions run again",
                file=sys.stderr,
            )
        plan = sweep_plan(spec)
        n_run = 0
        total = len(plan)
        if found.count >= total:  # a finished sweep: no cluster or pool started to run none
            EXECUTORS.get(executor)  # (a wrong name is still the one-line error)
            executor, scheduler = "inprocess", None
        with (
            open_executor(executor, workers, scheduler, WORKER_MODULES) as pool,
            _progress(progress, total, found.count) as advance,
        ):
            n_workers = 1 if executor == "inprocess" else executor_slots(pool, workers)
            size = auto_chunk_size(spec, chunk_size, n_workers, memory_bytes)
            local = sees_local_files(pool)
            with tempfile.TemporaryDirectory() as scratch:
                ship_modules(pool, policy_modules(spec), Path(scratch))
            shared = share(pool, plan)
            pending: set[Future] = set()
            for first, stop, skip in _chunk_ranges(plan, found, size):
                target = str(out) if local else None
                pending.add(pool.submit(run_range, shared, first, stop, skip, target))
                while len(pending) >= 2 * n_workers:
                    n_run += _collect(out, pending, advance)
            while pending:
                n_run += _collect(out, pending, advance)
        merged = store.consolidate(out, spec.level_columns)
        store.write_summary(out, merged.summary)
    seconds = time.perf_counter() - start
    return SweepOutcome(out, merged.summary, merged.rows, n_run, seconds)


def _collect(out: Path, pending: set[Future], advance: Any) -> int:
    done, _ = wait(pending, return_when=FIRST_COMPLETED)
    count = 0
    for future in done:
        pending.discard(future)
        n, part = future.result()
        if part is not None:  # a remote worker's part: stored here
            store.write_part_bytes(out, part)
        advance(n)
        count += n
    return count


class _Progress:
    def __init__(self, enabled: bool, total: int, done: int) -> None:
        self.enabled, self.total, self.done = enabled, total, done

    def __enter__(self) -> Any:
        if not self.enabled:
            return lambda n: None
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.bar = Progress(
            TextColumn("missions"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[rate]:>10} missions/s"),
            TimeElapsedColumn(),
            TextColumn("left"),
            TimeRemainingColumn(),
            console=Console(stderr=True),
        )
        self.bar.__enter__()
        self.task = self.bar.add_task("sweep", total=self.total, completed=self.done, rate="-")
        self.started = time.perf_counter()
        self.count = 0

        def advance(n: int) -> None:
            self.count += n
            rate = self.count / max(time.perf_counter() - self.started, 1e-9)
            self.bar.update(self.task, advance=n, rate=f"{rate:.0f}")

        return advance

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self.enabled:
            self.bar.__exit__(exc_type, exc, tb)


def _progress(enabled: bool, total: int, done: int) -> _Progress:
    return _Progress(enabled, total, done)

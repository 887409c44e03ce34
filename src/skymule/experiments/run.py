"""Running a sweep: plan, skip what is done, run chunks on an executor, store, summarise.

Fixed-trajectory Greedy/HGAD missions (per-slot fading included) run through the batched
engine (:mod:`skymule.sim.batch`), whose summaries come straight from the batch arrays
(``summarize_fixed_batch``: no per-mission log is built); every other mission (other policies,
autonomous flights) runs through the reference engine, one at a time, in the worker. Either way
the row is ``metrics.summarize`` of the mission's log, value for value, as ``skymule run``
gives.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, wait
from dataclasses import dataclass, replace
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
import pandas as pd

from skymule.experiments import store
from skymule.experiments.executors import default_workers, open_executor
from skymule.experiments.sweep import SweepMission, SweepSpec, iter_missions, validate_mission

Task = tuple[int, str, dict[str, Any], dict[str, Any]]
"""(mission index, mission id, axis values, resolved scenario dict)."""


@dataclass(frozen=True)
class SweepOutcome:
    """A finished sweep: all its rows, the per-policy summary and what this call ran."""

    results: pd.DataFrame
    summary: pd.DataFrame
    n_missions: int
    n_run: int
    seconds: float


def _flat_summary(summary: dict[str, Any]) -> dict[str, Any]:
    row: dict[str, Any] = {}
    for key, value in summary.items():
        if isinstance(value, dict):
            row.update({f"{key}.{name}": v for name, v in value.items()})
        elif isinstance(value, list | tuple):
            row[key] = ",".join(str(v) for v in value)
        else:
            row[key] = value
    return row


def _param_value(value: Any) -> Any:
    return json.dumps(value) if isinstance(value, list | dict) else value


def _geometry_key(data: dict[str, Any]) -> str:
    """Missions differing only in buffers, policy and name share one built Mission."""
    sensors = [{k: v for k, v in s.items() if k != "buffer_mbit"} for s in data["sensors"]]
    rest = {k: v for k, v in data.items() if k not in ("policy", "name", "sensors")}
    return json.dumps([rest, sensors], sort_keys=True, default=str)


def run_chunk(tasks: Sequence[Task], base_dir: str) -> pd.DataFrame:
    """Run a chunk of missions (in a worker); one row per mission, in task order."""
    from skymule.metrics import summarize
    from skymule.policies import make_policy
    from skymule.scenario import scenario_from_dict
    from skymule.sim.batch import batchable, summarize_fixed_batch
    from skymule.sim.run import run_mission
    from skymule.world import BITS_PER_MBIT, build_mission

    built: dict[str, Any] = {}
    summaries: list[dict[str, Any] | None] = [None] * len(tasks)
    batched: list[tuple[int, Any, Any, str]] = []
    for position, (_, mission_id, _, data) in enumerate(tasks):
        scenario = scenario_from_dict(data, f"mission {mission_id}", Path(base_dir))
        key = _geometry_key(data)
        if key not in built:
            built[key] = build_mission(scenario)
        buffers = np.array([s.buffer_mbit for s in scenario.sensors], float) * BITS_PER_MBIT
        mission = replace(built[key], scenario=scenario, buffers_bit=buffers)
        if batchable(mission, scenario.policy):
            batched.append((position, mission, scenario.policy, key))
        else:
            log = run_mission(mission, make_policy(scenario.policy))
            summaries[position] = summarize(log, scenario.name)
    if batched:
        rows_batched = summarize_fixed_batch(
            [m for _, m, _, _ in batched],
            [s for _, _, s, _ in batched],
            [m.scenario.name for _, m, _, _ in batched],
        )
        for (position, _, _, _), batch_summary in zip(batched, rows_batched, strict=True):
            summaries[position] = batch_summary
    rows = []
    for (index, mission_id, params, _), summary in zip(tasks, summaries, strict=True):
        assert summary is not None
        row = {"mission_index": index, "mission_id": mission_id}
        row.update({k: _param_value(v) for k, v in params.items()})
        row.update(_flat_summary(summary))
        rows.append(row)
    return pd.DataFrame(rows)


def plan(spec: SweepSpec) -> list[str]:
    """Validate every mission (before any runs) and return their ids in sweep order."""
    from skymule.world import build_mission

    ids = []
    for mission in iter_missions(spec):
        scenario = validate_mission(spec, mission)
        if mission.index == 0:
            build_mission(scenario)  # geometry checks (fence, slot count) on the first one
        ids.append(mission.mission_id)
    return ids


def _chunks(spec: SweepSpec, missing: set[str], size: int) -> Iterator[list[Task]]:
    chunk: list[Task] = []
    for mission in iter_missions(spec):
        if mission.mission_id in missing:
            chunk.append(_task(mission))
            if len(chunk) == size:
                yield chunk
                chunk = []
    if chunk:
        yield chunk


def _task(mission: SweepMission) -> Task:
    return (mission.index, mission.mission_id, mission.params, mission.scenario)


def run_sweep(
    spec: SweepSpec,
    out: Path,
    *,
    executor: str = "process",
    workers: int | None = None,
    scheduler: str | None = None,
    chunk_size: int = 500,
    progress: bool = True,
) -> SweepOutcome:
    """Run the missions of ``spec`` not yet in ``out``, then consolidate and summarise."""
    from skymule.errors import SkymuleError

    if chunk_size < 1:
        raise SkymuleError(f"--chunk-size {chunk_size}: allowed: an integer >= 1")
    start = time.perf_counter()
    ids = plan(spec)
    if len(set(ids)) != len(ids):
        raise SkymuleError(
            f"{spec.source}: two missions resolve to the same scenario; "
            "remove the repeated axis values"
        )
    out.mkdir(parents=True, exist_ok=True)
    missing = set(ids) - store.done_ids(out)
    base_dir = spec.base.base_dir
    n_run = 0
    if missing:
        n_workers = 1 if executor == "inprocess" else (workers or default_workers())
        with (
            open_executor(executor, workers, scheduler) as pool,
            _progress(progress, len(ids), len(ids) - len(missing)) as advance,
        ):
            pending: set[Future] = set()
            for chunk in _chunks(spec, missing, chunk_size):
                pending.add(pool.submit(run_chunk, chunk, base_dir))
                while len(pending) >= 2 * n_workers:
                    n_run += _collect(out, pending, advance)
            while pending:
                n_run += _collect(out, pending, advance)
    results = store.consolidate(out, ids)
    summary = store.summary_table(results)
    store.write_summary(out, summary)
    return SweepOutcome(results, summary, len(ids), n_run, time.perf_counter() - start)


def _collect(out: Path, pending: set[Future], advance: Any) -> int:
    done, _ = wait(pending, return_when=FIRST_COMPLETED)
    count = 0
    for future in done:
        pending.discard(future)
        frame = future.result()
        store.write_part(out, frame)
        advance(len(frame))
        count += len(frame)
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

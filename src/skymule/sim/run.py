"""Run missions: the engine of their trajectory mode, any policy, one record.

* :func:`run_missions` -- B missions (or the UAV columns of fleet missions) under one
  policy, batched or per-mission (:func:`~skymule.policies.batched.as_batch_policy`);
* :func:`run_mission` -- one mission, a batch of one, as its :class:`MissionLog`;
* :func:`summarize_missions` -- ``summary.json`` rows of many missions, each under its own
  ``[policy]``, batched by what can share a batch (mode, sensor count, geofence) and, for
  policies with a compiled twin, summarised inside the compiled loop without a per-slot log.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.metrics.flights import Flights, MissionLog
from skymule.metrics.summary import summary_dicts, summary_rows, with_battery
from skymule.policies.base import BatchPolicy, MissionContext, Policy
from skymule.policies.batched import as_batch_policy, policy_names
from skymule.scenario import PolicySpec
from skymule.sim import compiled
from skymule.world import Mission


def run_missions(
    missions: Sequence[Mission],
    policy: BatchPolicy | Policy | Sequence[Policy],
    *,
    fleet: np.ndarray | None = None,
    detail: bool = True,
    engine: str = "auto",
) -> Flights:
    """Run B missions (one trajectory mode, one sensor count) under ``policy``; the record.

    ``policy``: a batched policy, one per-mission policy (for B = 1) or one per mission.
    ``fleet``: (B,) the fleet mission of each column (its UAVs share buffers); ``detail``:
    keep per-slot SNR, rates and buffers (run folders); ``engine``: one of
    :data:`skymule.sim.compiled.ENGINES`.
    """
    compiled.check_engine(engine)
    batch = as_batch_policy(policy)
    modes = {m.mode for m in missions}
    if len(modes) != 1:
        raise SkymuleError(f"one batch runs one trajectory mode, got {sorted(modes)}")
    mode = modes.pop()
    if mode == "fixed":
        from skymule.sim.fixed import run_fixed

        return run_fixed(missions, batch, fleet=fleet, detail=detail, engine_choice=engine)
    if mode == "autonomous":  # its engine (fence, paths, wind) costs ~0.1 s to import
        from skymule.sim.autonomous import run_autonomous

        return run_autonomous(missions, batch, fleet=fleet, detail=detail, engine=engine)
    raise SkymuleError(f"trajectory.mode = {mode!r} is not supported; allowed: fixed, autonomous")


def mission_context(mission: Mission) -> MissionContext:
    """What a policy's ``reset`` gets for ``mission``: the engine's context of a batch of one."""
    from skymule.sim.autonomous import AutonomousEngine
    from skymule.sim.fixed import FixedEngine

    engine = AutonomousEngine([mission]) if mission.mode == "autonomous" else FixedEngine([mission])
    return engine.contexts()[0]


def run_mission(mission: Mission, policy: BatchPolicy | Policy, engine: str = "auto") -> MissionLog:
    """One mission under ``policy`` (a batch of one): its log."""
    return MissionLog(run_missions([mission], policy, engine=engine))


#: Bytes per mission-slot and sensor a batch holds (float buffers, rates and SNR seen), and
#: per mission-slot (served, downloaded, sample, hovering, ...).
BYTES_PER_SLOT_SENSOR = 40
BYTES_PER_SLOT = 48

#: A batch holds at most this much (its logs and tables): :func:`batch_groups` caps it.
BATCH_MEMORY_BYTES = 256 * 2**20


def batch_bytes(n_slots: int, n_sensors: int) -> int:
    """Estimated bytes one mission of ``n_slots`` slots and ``n_sensors`` sensors adds to a
    batch."""
    return n_slots * (BYTES_PER_SLOT + BYTES_PER_SLOT_SENSOR * max(1, n_sensors))


def batch_groups(missions: Sequence[Mission], batch_size: int) -> Iterator[list[int]]:
    """Indices of missions that can share a batch (mode, sensor count, autonomous: geofence),
    at most ``batch_size`` each and within :data:`BATCH_MEMORY_BYTES`; within a group longest
    first, so that the missions of one batch end at about the same slot (a mission that is
    over costs its batch a little every slot until the batch ends)."""
    groups: dict[tuple[Any, ...], list[int]] = {}
    for index, mission in enumerate(missions):
        fence = mission.navigator.fence_key if mission.navigator is not None else b""
        groups.setdefault((mission.mode, mission.n_sensors, fence), []).append(index)
    for indices in groups.values():
        indices = sorted(indices, key=lambda i: -missions[i].n_slots)  # stable: ties in order
        longest = missions[indices[0]]
        by_memory = BATCH_MEMORY_BYTES // batch_bytes(longest.n_slots, longest.n_sensors)
        size = max(1, min(batch_size, by_memory))
        for start in range(0, len(indices), size):
            yield indices[start : start + size]


def summarize_missions(
    missions: Sequence[Mission],
    specs: Sequence[PolicySpec],
    scenario_names: Sequence[str],
    *,
    batch_size: int = 4096,
    engine: str = "auto",
) -> list[dict[str, Any]]:
    """``summary.json`` rows of ``missions``, each under its own ``[policy]``, in input order.

    Equal to ``summarize(run_mission(m, make_policy(s)), name)`` for each, value for value:
    the summaries come from the batch record (numpy, or the compiled pass over it when
    numba is installed) or, for a fixed batch whose policy has a compiled twin, from the
    compiled loop's per-mission reductions (no per-slot log at all).
    """
    from skymule.policies import batch_policy
    from skymule.sim.compiled_summaries import compiled_summaries, flights_summaries
    from skymule.sim.fixed import FixedEngine, compiled_reason

    compiled.check_engine(engine)
    rows: list[dict[str, Any] | None] = [None] * len(missions)
    for part in batch_groups(missions, batch_size):
        chosen = [missions[i] for i in part]
        policy = batch_policy([specs[i] for i in part])
        names = [scenario_names[i] for i in part]
        dicts: list[dict[str, Any]]
        if chosen[0].mode == "fixed" and engine != "numpy" and _may_have_rule(policy):
            fixed = FixedEngine(chosen, detail=False)
            policy.reset(fixed.contexts())
            rule = getattr(policy, "slot_rule", lambda: None)()
            if compiled_reason(fixed, rule) is None:
                dicts = summary_dicts(
                    compiled_summaries(fixed, rule),
                    [m.sensor_names for m in chosen],
                    list(policy_names(policy, len(chosen))),
                    names,
                )
                for i, row in zip(part, dicts, strict=True):
                    rows[i] = row
                continue
            policy = batch_policy([specs[i] for i in part])  # a fresh one for the slot loop
        flights = run_missions(chosen, policy, detail=False, engine=engine)
        if engine != "numpy" and compiled.available():
            dicts = with_battery(
                flights,
                summary_dicts(
                    flights_summaries(flights),
                    list(flights.sensor_names),
                    list(flights.policy),
                    names,
                ),
            )
        else:
            dicts = summary_rows(flights, names)
        for i, row in zip(part, dicts, strict=True):
            rows[i] = row
    return [row for row in rows if row is not None]


def _may_have_rule(policy: Any) -> bool:
    """False when ``policy`` has no compiled twin whatever its reset (no ``slot_rule``, or a
    :class:`~skymule.policies.batched.Columns` with a part without one): it then goes to the
    slot loop directly, reset once, not first for a rule it cannot have."""
    parts = getattr(policy, "parts", None)
    if parts is not None:
        return all(hasattr(part, "slot_rule") for part, _ in parts)
    return hasattr(policy, "slot_rule")

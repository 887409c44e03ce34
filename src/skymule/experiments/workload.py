"""How long a sweep would take in this process, estimated before it runs, and the executor
that finishes it sooner: ``skymule sweep --executor auto`` (the default).

A ``process`` pool pays for starting its workers (each imports skymule and loads the compiled
engine: ~2 s) and then divides the work by the number of workers. It finishes sooner than
``inprocess`` only when the work W (seconds in one process) exceeds
``WORKER_START_S * n / (n - 1)``: ~4 s on two cores, ~27,000 fixed-path missions. The
docs/sweeps.md 1,000-mission example is ~0.15 s of work and ran 2-4x slower under ``process``
(``benchmarks/bench_sweep.py``: ``process-10k`` against ``sample-10k``).

The work is the number of missions times a cost per mission that depends on how the mission
runs: fixed-path Greedy and HGAD in the batched compiled loop, autonomous Greedy and HGAD in
the batched autonomous engine, any other policy one mission at a time
(:func:`skymule.sim.run.summarize_missions`). The costs were measured with
``skymule sweep --executor inprocess`` on this 2-core machine (500-slot presets; CPU seconds
per mission beyond the sweep's own start) and scale with the number of slots.
"""

from __future__ import annotations

import math

from skymule.experiments.sweep import SweepSpec

SECONDS_PER_MISSION = {"fixed-batched": 1.5e-4, "autonomous-batched": 2e-2, "one-at-a-time": 0.15}
"""CPU seconds per 500-slot mission in one process, by how the mission runs (fixed-batched:
``bench_sweep.py``'s ``sample-10k``, 138 us a mission with the sweep's own costs, since the
sweep builds missions rather than scenarios; it was 4e-4)."""

REFERENCE_SLOTS = 500
"""Slots of the missions :data:`SECONDS_PER_MISSION` was measured on."""

BATCHED_POLICIES = ("greedy", "hgad")
"""Policies with a batched rule in both engines (``slot_rule``); others run one at a time."""

WORKER_START_S = 2.0
"""Seconds a ``process`` worker takes to start (imports, the compiled engine's cache)."""


def _values(spec: SweepSpec, key: str, base: object) -> list[object]:
    """The values the sweep gives ``key``: its axis' values, or the base scenario's."""
    for axis in spec.discrete:
        if axis.key == key and axis.values:
            return list(axis.values)
    return [base]


def mission_seconds(mode: str, policy: str, slots: int) -> float:
    """Estimated CPU seconds of one mission of ``slots`` slots in one process."""
    batched = policy in BATCHED_POLICIES
    kind = f"{mode}-batched" if batched and mode in ("fixed", "autonomous") else "one-at-a-time"
    return SECONDS_PER_MISSION[kind] * max(1.0, slots / REFERENCE_SLOTS)


def estimated_seconds(spec: SweepSpec) -> float:
    """Estimated seconds the sweep's missions take in one process: missions x the slowest
    cost per mission among the sweep's trajectory modes and policies."""
    base = spec.base
    duration = base.mission.duration_s or 3600.0  # a trace's length is not known here
    slots = max(1, math.ceil(duration / base.mission.slot_s))
    modes = _values(spec, "trajectory.mode", base.trajectory.mode)
    policies = _values(spec, "policy.name", base.policy.name)
    slowest = max(mission_seconds(str(m), str(p), slots) for m in modes for p in policies)
    return len(spec) * slowest


def choose_executor(spec: SweepSpec, workers: int) -> str:
    """``process`` when ``workers`` (> 1) processes would finish ``spec`` sooner than this
    process alone (see the module docstring), else ``inprocess``."""
    if workers < 2:
        return "inprocess"
    worth = WORKER_START_S * workers / (workers - 1)
    return "process" if estimated_seconds(spec) > worth else "inprocess"

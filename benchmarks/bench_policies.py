"""Your own policy on the engine: batched and per-mission forms, fixed and autonomous.

Run: python benchmarks/bench_policies.py [n_fixed [n_autonomous [n_single [repeats]]]] [--json PATH]
(``--json benchmarks/results/policies.json``: the speed table's own-policy rows, docs/speed.md)
(SKYMULE_BENCH_TINY=1: a few missions, 1 repeat; the figures are then no measurements)

The policies are the README's "Your own policy" examples, written both ways:

* fixed paths: serve sensor 0 while it has data (``ServeFirst`` / ``ServeFirstBatched``);
* autonomous: fly to the hover point of the sensor with the most data left, serving the
  strongest link with data on the way; home when every buffer is empty
  (``LargestFirst`` / ``LargestFirstBatched``).

It prints, each figure the best of ``repeats`` runs (CPU time of this process: the machine is
shared):

1. the batched form over ``n_fixed`` paper-sim-fixed missions with random buffers, the sweep
   path (``skymule.sim.run.summarize_missions``, summaries included): mission-slots per CPU-s;
2. the per-mission form one mission at a time (``run_mission``, a batch of one) and the
   batched form's cost per mission against it (target: >= 100x less), with the totals of both
   forms compared mission for mission (they must be equal);
3. the same for the autonomous pair on ``n_autonomous`` random layouts: missions per CPU-s;
4. the engine's own cost per slot beyond the policy's ``act`` for a per-mission policy, in a
   batch (a sweep) and in a batch of one (one run): the run's CPU time less the time its
   ``act`` calls take on their own, per mission-slot.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from _results import json_option, table, write
from _sizes import size
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.policies.base import (
    Action,
    BatchAction,
    BatchObservation,
    MissionContext,
    Observation,
)
from skymule.policies.batched import PerMission
from skymule.scenario import PolicySpec, load_scenario
from skymule.sim.run import run_mission, run_missions, summarize_missions
from skymule.world import Mission, build_mission

PLUGIN = "bench_policies"  # this file, importable as a module (benchmarks/ is on the path)


# --- the README's policies, both forms ----------------------------------------------------


class ServeFirst:
    """Serve sensor 0 while it has data (one mission)."""

    name = "serve-first"

    def reset(self, context: MissionContext) -> None:
        pass

    def act(self, observation: Observation) -> Action:
        return Action(serve=0 if observation.remaining_bit[0] > 0 else None)


class ServeFirstBatched:
    """Serve sensor 0 while it has data (B missions at once)."""

    name = "serve-first"
    batched = True

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        pass

    def act(self, observation: BatchObservation) -> BatchAction:
        return BatchAction(serve=np.where(observation.remaining_bit[:, 0] > 0, 0, -1))


class LargestFirst:
    """Fly to the hover point of the sensor with the most data left, serving the strongest
    link with data on the way; home when every buffer is empty (one mission)."""

    name = "largest-first"

    def reset(self, context: MissionContext) -> None:
        assert context.hover_points_m is not None and context.home_m is not None
        self.hover = np.asarray(context.hover_points_m)
        self.home = (float(context.home_m[0]), float(context.home_m[1]))

    def act(self, observation: Observation) -> Action:
        left = observation.remaining_bit
        usable = (left > 0) & (observation.rate_bps > 0)
        serve = int(np.argmax(np.where(usable, observation.snr_db, -np.inf)))
        if not (left > 0).any():
            return Action(serve=serve if usable.any() else None, goto_m=self.home)
        target = int(np.argmax(left))
        goal = (float(self.hover[target, 0]), float(self.hover[target, 1]))
        return Action(serve=serve if usable.any() else None, goto_m=goal, target=target)


class LargestFirstBatched:
    """:class:`LargestFirst` for B missions at once."""

    name = "largest-first"
    batched = True

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        self.hover = np.array([c.hover_points_m for c in contexts], float)  # (B, N, 2)
        self.home = np.array([c.home_m for c in contexts], float)  # (B, 2)

    def act(self, observation: BatchObservation) -> BatchAction:
        left = observation.remaining_bit
        usable = (left > 0) & (observation.rate_bps > 0)
        serve = np.argmax(np.where(usable, observation.snr_db, -np.inf), axis=1)
        serve = np.where(usable.any(axis=1), serve, -1)
        target = np.argmax(left, axis=1)
        rows = np.arange(left.shape[0])
        has_data = (left > 0).any(axis=1)
        goto = np.where(has_data[:, None], self.hover[rows, target], self.home)
        return BatchAction(serve=serve, goto_m=goto, target=np.where(has_data, target, -1))


# --- measuring ----------------------------------------------------------------------------


def best_cpu_seconds(run: Callable[[], object], repeats: int) -> float:
    """The least CPU time of ``repeats`` runs (another job's burst only ever adds time)."""
    best = float("inf")
    for _ in range(repeats):
        start = time.process_time()
        run()
        best = min(best, time.process_time() - start)
    return max(best, 1e-9)


def act_seconds(policy: Any, mission: Mission, calls: int = 20_000) -> float:
    """CPU seconds one ``act`` call of ``policy`` takes on its own, on the mission's first
    observation (what the engine's overhead is measured beyond)."""
    flights = run_missions([mission], policy, detail=True)
    log = flights.mission(0)
    seen = Observation(0, log.position_m[0], log.snr_db[0], log.rate_bps[0], log.buffers_bit)
    start = time.process_time()
    for _ in range(calls):
        policy.act(seen)
    return (time.process_time() - start) / calls


def compare_forms(
    label: str,
    missions: list[Mission],
    batched: str,
    single: Callable[[], Any],
    n_single: int,
    repeats: int,
    unit: str,
) -> dict[str, Any]:
    """The batched form on every mission (sweep path) against the per-mission form one
    mission at a time on the first ``n_single``; totals compared mission for mission."""
    spec = PolicySpec(name=f"{PLUGIN}:{batched}")
    names = [m.scenario.name for m in missions]
    rows: list[dict[str, Any]] = []

    def sweep() -> None:
        rows[:] = summarize_missions(missions, [spec] * len(missions), names)

    sweep()  # warm up (imports, compiled path queries)
    batch_s = best_cpu_seconds(sweep, repeats)
    slots = sum(int(r["slots"]) for r in rows)
    alone: list[float] = []

    def one_at_a_time() -> None:
        alone[:] = [
            float(run_mission(m, single()).downloaded_bit.sum()) for m in missions[:n_single]
        ]

    single_s = best_cpu_seconds(one_at_a_time, repeats)
    same = all(
        alone[k] / 1e6 == rows[k]["total_downloaded_mbit"] for k in range(min(n_single, len(rows)))
    )
    per_batch, per_single = batch_s / len(missions), single_s / n_single
    if unit == "slots":
        print(f"{label}: batched, {len(missions)} missions + summaries: "
              f"{slots / batch_s / 1e6:.2f} M mission-slots per CPU-s")  # fmt: skip
    else:
        print(f"{label}: batched, {len(missions)} missions + summaries: "
              f"{len(missions) / batch_s:,.0f} missions per CPU-s")  # fmt: skip
    print(
        f"{label}: per-mission form, one mission at a time: {per_single * 1e3:.2f} ms per "
        f"mission; batched {per_batch * 1e6:.1f} us per mission: {per_single / per_batch:.0f}x "
        f"less (target >= 100); totals equal: {same}"
    )
    rate = slots / batch_s if unit == "slots" else len(missions) / batch_s
    return {"rate": rate, "single": per_single, "batch": per_batch, "same": same}


def overhead(
    label: str, mission: Mission, policy: Callable[[], Any], n: int, repeats: int
) -> dict[int, float]:
    """The engine's CPU per slot beyond ``act`` for a per-mission policy, in a batch of ``n``
    and in a batch of one [s], by batch size."""
    per_act = act_seconds(policy(), mission)
    found = {}
    for count in (n, 1):
        missions = [mission] * count
        flights = run_missions(missions, PerMission([policy() for _ in missions]), detail=False)
        slots = int(flights.n_run.sum())
        seconds = best_cpu_seconds(
            lambda m=missions: run_missions(m, PerMission([policy() for _ in m]), detail=False),
            repeats,
        )
        beyond = seconds / slots - per_act
        where = f"a batch of {count:,}" if count > 1 else "a batch of one"
        print(f"{label}: engine overhead beyond act, {where}: {beyond * 1e6:.2f} us per slot "
              f"(act itself {per_act * 1e6:.2f} us)")  # fmt: skip
        found[count] = beyond
    return found


def main(
    n_fixed: int = size(4000, 20),
    n_autonomous: int = size(1000, 6),
    n_single: int = size(20, 2),
    repeats: int = size(3, 1),
    json_path: Path | None = None,
) -> None:
    fixed = build_mission(load_scenario("paper-sim-fixed"))
    rng = np.random.default_rng(0)
    fixed_missions = [
        replace(fixed, buffers_bit=rng.uniform(200e6, 1500e6, fixed.n_sensors))
        for _ in range(n_fixed)
    ]
    fixed_forms = compare_forms(
        "fixed (paper-sim-fixed, serve sensor 0)", fixed_missions, "ServeFirstBatched",
        ServeFirst, n_single, repeats, "slots",
    )  # fmt: skip
    base = load_scenario("paper-sim-autonomous")
    ranges = LayoutRanges(n_sensors=(4, 4))
    layouts = [
        build_mission(random_autonomous_scenario(rng, base, ranges)) for _ in range(n_autonomous)
    ]
    auto_forms = compare_forms(
        "autonomous (random layouts, largest first)", layouts, "LargestFirstBatched",
        LargestFirst, n_single, repeats, "missions",
    )  # fmt: skip
    batch = size(1000, 4)
    fixed_cost = overhead("fixed, per-mission policy", fixed, ServeFirst, batch, repeats)
    auto = build_mission(base)
    auto_cost = overhead("autonomous, per-mission policy", auto, LargestFirst, batch, repeats)
    f, a = fixed_forms, auto_forms
    rows = [
        [
            f"your own batched policy, fixed: {n_fixed:,} × paper-sim-fixed in one batch "
            "(`summarize_missions`; a sweep's chunks are ≤ 500 missions), serve sensor 0 while "
            "it has data",
            f"{f['rate'] / 1e6:.1f} M mission-slots per CPU-s with summaries; the per-mission "
            f"form one mission at a time {f['single'] * 1e3:.1f} ms a mission, "
            f"**×{f['single'] / f['batch']:.0f}** the batched form's {f['batch'] * 1e6:.0f} µs; "
            f"totals equal: {str(f['same']).lower()}",
            "`python benchmarks/bench_policies.py`",
        ],
        [
            f"your own batched policy, autonomous: {n_autonomous:,} random layouts "
            "of 4 sensors (`summarize_missions`), largest buffer first",
            f"{a['rate']:,.0f} missions per CPU-s with summaries; the per-mission form one at a "
            f"time {a['single'] * 1e3:.0f} ms a mission, **×{a['single'] / a['batch']:.0f}** the "
            f"batched form's {a['batch'] * 1e6:.0f} µs; totals equal: {str(a['same']).lower()}",
            "same",
        ],
        [
            "your own per-mission policy: the engine's CPU per slot beyond `act`",
            f"fixed {fixed_cost[batch] * 1e6:.1f} µs in a batch of {batch:,} "
            f"({fixed_cost[1] * 1e6:.0f} µs alone); autonomous {auto_cost[batch] * 1e6:.1f} µs "
            f"({auto_cost[1] * 1e6:.0f} µs alone)",
            "same",
        ],
    ]
    write(json_path, {"speed-policies": table(["what", "figure", "command"], rows, align="lll")})


if __name__ == "__main__":
    json_path = json_option()
    names = ("n_fixed", "n_autonomous", "n_single", "repeats")
    sizes = {name: int(a) for name, a in zip(names, sys.argv[1:], strict=False)}
    main(**sizes, json_path=json_path)

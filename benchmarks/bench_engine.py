"""Batched vs single-mission engine on 1,000 missions of paper-sim-fixed (random buffers).

Run: python benchmarks/bench_engine.py [n_missions] [n_single] [repeats]
(SKYMULE_BENCH_TINY=1: 20 missions, 2 single, 1 repeat)

Prints mission-slots per second (same machine, same run) of:

* single: ``engine.run_fixed`` one mission at a time (its MissionLog);
* batched, logs: ``run_fixed_batch`` (one MissionLog per mission, for tests and users);
* batched, summaries: ``summarize_fixed_batch`` (the ``metrics.summarize`` dictionaries from
  the batch arrays, no MissionLog) -- what sweeps run, so the figure issue 6's 50x is about;
* slot loop only: ``run_batch`` on a stacked batch;

and each one's speed-up over single. Each figure is the best of ``repeats`` runs (the machine
is shared; the best run is the least disturbed one).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from _sizes import size

from skymule.policies import make_policy
from skymule.scenario import PolicySpec, load_scenario
from skymule.sim.autonomous import fixed_geometry_fields
from skymule.sim.batch import run_batch, run_fixed_batch, stack_missions, summarize_fixed_batch
from skymule.sim.engine import run_fixed
from skymule.world import Mission, build_mission


def best_seconds(run: Callable[[], object], repeats: int) -> float:
    """Shortest wall time of ``repeats`` calls of ``run`` [s]."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return min(times)


def bench_policy(
    name: str,
    missions: list[Mission],
    geometry: list[dict[str, object]],
    n_single: int,
    repeats: int,
) -> None:
    """Print the mission-slots/s of each engine path under policy ``name``, and speed-ups."""
    n_missions = len(missions)
    specs = [PolicySpec(name=name)] * n_missions
    names = [m.scenario.name for m in missions]
    slots = sum(row["slots"] for row in summarize_fixed_batch(missions, specs, names, geometry))
    single = missions[:n_single]
    single_slots = sum(run_fixed(m, make_policy(specs[0])).n_slots for m in single)
    single_s = best_seconds(lambda: [run_fixed(m, make_policy(specs[0])) for m in single], repeats)
    single_rate = single_slots / single_s
    print(f"{name:6s} {'single (' + str(n_single) + ' missions)':26s} {single_rate:12,.0f}")
    paths: dict[str, Callable[[], object]] = {
        "batched, logs": lambda: run_fixed_batch(missions, specs, batch_size=n_missions),
        "batched, summaries": lambda: summarize_fixed_batch(
            missions, specs, names, geometry, batch_size=n_missions
        ),
        "slot loop only": lambda: run_batch(stack_missions(missions, specs)),
    }
    for label, run in paths.items():
        seconds = best_seconds(run, repeats)
        rate = slots / seconds
        print(f"{name:6s} {label:26s} {rate:12,.0f}  ({seconds:.3f} s)  x{rate / single_rate:.0f}")


def main(n_missions: int = 1000, n_single: int = 100, repeats: int = 3) -> None:
    base = build_mission(load_scenario("paper-sim-fixed"))
    rng = np.random.default_rng(0)
    missions = [
        replace(base, buffers_bit=rng.uniform(200e6, 1500e6, base.n_sensors))
        for _ in range(n_missions)
    ]
    geometry = [fixed_geometry_fields(base)] * n_missions
    print(f"{n_missions} missions x {base.n_slots} slots, best of {repeats}; mission-slots/s")
    for name in ("hgad", "greedy"):
        bench_policy(name, missions, geometry, n_single, repeats)


if __name__ == "__main__":
    defaults = size((1000, 100, 3), (20, 2, 1))
    given = [int(a) for a in sys.argv[1:]]
    main(*given, *defaults[len(given) :])

"""Batched vs single-mission engine on 1,000 missions of paper-sim-fixed (random buffers).

Run: /work/venv/bin/python benchmarks/bench_engine.py [n_missions] [n_single]
Prints mission-slots per second of each engine and the speed-up (same machine, same run).
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace

import numpy as np

from skymule.engine import run_fixed
from skymule.engine_batch import run_batch, run_fixed_batch, stack_missions
from skymule.policies import make_policy
from skymule.scenario import PolicySpec, load_scenario
from skymule.world import build_mission


def main(n_missions: int = 1000, n_single: int = 100) -> None:
    base = build_mission(load_scenario("paper-sim-fixed"))
    rng = np.random.default_rng(0)
    missions = [
        replace(base, buffers_bit=rng.uniform(200e6, 1500e6, base.n_sensors))
        for _ in range(n_missions)
    ]
    for name in ("hgad", "greedy"):
        specs = [PolicySpec(name=name)] * n_missions
        start = time.perf_counter()
        logs = run_fixed_batch(missions, specs, batch_size=n_missions)
        batched_s = time.perf_counter() - start
        slots = sum(log.n_slots for log in logs)
        start = time.perf_counter()
        run_batch(stack_missions(missions, specs))
        loop_s = time.perf_counter() - start
        start = time.perf_counter()
        single = [run_fixed(m, make_policy(specs[0])) for m in missions[:n_single]]
        single_s = time.perf_counter() - start
        single_slots = sum(log.n_slots for log in single)
        batched_rate = slots / batched_s
        single_rate = single_slots / single_s
        print(
            f"{name:6s} single: {single_rate:12,.0f} mission-slots/s ({n_single} missions)  "
            f"batched: {batched_rate:12,.0f} mission-slots/s ({n_missions} missions, "
            f"{batched_s:.2f} s)  speed-up x{batched_rate / single_rate:.0f} with logs, "
            f"x{slots / loop_s / single_rate:.0f} slot loop only"
        )


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))

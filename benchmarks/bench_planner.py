"""Planner vs HGAD over random autonomous missions, with the autonomous upper bound.

Random missions (seeded): 3-6 sensors anywhere within 300 m of the Lake Wheeler fence, buffers
300-1500 Mbit, 200-450 s, home at a random in-fence point, 6-12 m/s, free space at 3.41 GHz
(the paper-sim-autonomous radio), return home. Prints the mean and worst-case gain of planner
over HGAD, how many missions it loses by more than 1 %, the mean gap to the bound (geodesic
reach, the default, and the straight-line reach it tightens), the bound's run time, and the
preset's time-to-complete / AADM score.

Run: /work/venv/bin/python benchmarks/bench_planner.py [--missions 200] [--workers 2]
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from skymule.bounds.autonomous import autonomous_bound
from skymule.experiments.layouts import random_autonomous_scenario
from skymule.metrics import aadm_score, completion_time_s
from skymule.policies.hgad import HGAD
from skymule.policies.planner import Planner
from skymule.scenario import Scenario, load_scenario
from skymule.sim.run import run_mission
from skymule.world import build_mission

PRESET = "paper-sim-autonomous"
SEED = 20250601


def evaluate(scenario: Scenario) -> tuple[float, ...]:
    """(total, hgad, planner, geodesic bound, euclidean bound [bit], planner s, bound s)."""
    mission = build_mission(scenario)
    hgad = float(run_mission(mission, HGAD()).downloaded_bit.sum())
    start = time.perf_counter()
    planner = float(run_mission(mission, Planner()).downloaded_bit.sum())
    took = time.perf_counter() - start
    start = time.perf_counter()
    bound = autonomous_bound(mission).upper_bound_bit
    bound_took = time.perf_counter() - start
    euclidean = autonomous_bound(mission, reach="euclidean").upper_bound_bit
    total = float(mission.buffers_bit.sum())
    return total, hgad, planner, bound, euclidean, took, bound_took


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--missions", type=int, default=200)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()

    base = load_scenario(PRESET)
    mission = build_mission(base)
    print(f"{PRESET} (all 3000 Mbit fit): policy, Mbit, time to complete s, AADM score")
    for policy in (HGAD(), Planner()):
        log = run_mission(mission, policy)
        print(
            f"  {policy.name:8s} {log.downloaded_bit.sum() / 1e6:7.1f} "
            f"{completion_time_s(log)!s:>6} {aadm_score(log):7.1f}"
        )
    for label, changes in (
        ("300 s", {"mission": base.mission.model_copy(update={"duration_s": 300.0})}),
        (
            "1500 Mbit each",
            {"sensors": [s.model_copy(update={"buffer_mbit": 1500.0}) for s in base.sensors]},
        ),
    ):
        variant = build_mission(base.model_copy(update=changes))
        bound = autonomous_bound(variant).upper_bound_bit / 1e6
        euclidean = autonomous_bound(variant, reach="euclidean").upper_bound_bit / 1e6
        got = [run_mission(variant, p).downloaded_bit.sum() / 1e6 for p in (HGAD(), Planner())]
        print(
            f"  {label}: hgad {got[0]:.1f}, planner {got[1]:.1f}, bound {bound:.1f} Mbit "
            f"(straight-line reach {euclidean:.1f})"
        )

    rng = np.random.default_rng(SEED)
    scenarios = [random_autonomous_scenario(rng, base) for _ in range(args.missions)]
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        rows = np.array(list(pool.map(evaluate, scenarios, chunksize=4)))
    wall = time.perf_counter() - start
    total, hgad, planner, bound, euclidean, took, bound_took = rows.T
    gain = (planner - hgad) / hgad
    gap = (bound - planner) / bound
    gap_euclidean = (euclidean - planner) / euclidean
    print(f"{args.missions} random missions (seed {SEED}), {wall:.0f} s on {args.workers} workers")
    print(f"  missions where the bound < total buffer: {(bound < total * (1 - 1e-9)).sum()}")
    print(
        f"  mean Mbit: hgad {hgad.mean() / 1e6:.1f}, planner {planner.mean() / 1e6:.1f}, "
        f"bound {bound.mean() / 1e6:.1f} (straight-line reach {euclidean.mean() / 1e6:.1f}), "
        f"total {total.mean() / 1e6:.1f}"
    )
    print(
        f"  geodesic reach tightens the bound in {(bound < euclidean * (1 - 1e-9)).sum()} "
        f"missions (by {((euclidean - bound) / euclidean).mean():.2%} on average, "
        f"{((euclidean - bound) / euclidean).max():.2%} at most); looser in "
        f"{(bound > euclidean * (1 + 1e-9)).sum()}"
    )
    print(
        f"  planner gain over hgad: mean {gain.mean():+.2%}, median {np.median(gain):+.2%}, "
        f"worst {gain.min():+.2%}, best {gain.max():+.2%}"
    )
    print(
        f"  planner below hgad by > 1 %: {(gain < -0.01).sum()} missions; below at all: "
        f"{(gain < -1e-9).sum()}"
    )
    print(
        f"  mean gap to bound (geodesic reach): planner {gap.mean():.2%}, "
        f"hgad {((bound - hgad) / bound).mean():.2%}"
    )
    print(
        f"  mean gap to bound (straight-line reach): planner {gap_euclidean.mean():.2%}, "
        f"hgad {((euclidean - hgad) / euclidean).mean():.2%}"
    )
    above = (planner > bound * (1 + 1e-9)) | (hgad > bound * (1 + 1e-9))
    print(f"  any policy above the bound: {above.sum()}")
    print(f"  planner run time: mean {took.mean():.2f} s, max {took.max():.2f} s per mission")
    print(
        f"  bound run time (geodesic): mean {bound_took.mean() * 1e3:.0f} ms, "
        f"max {bound_took.max() * 1e3:.0f} ms per mission"
    )


if __name__ == "__main__":
    main()

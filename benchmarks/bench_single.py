"""Slots simulated per second by the reference single-mission engine on the presets.

Run: python benchmarks/bench_single.py [--repeat N] (SKYMULE_BENCH_TINY=1: --repeat 1)
"""

from __future__ import annotations

import argparse
import time

from _results import json_option, table, write
from _sizes import size
from skymule.policies import make_policy
from skymule.scenario import load_scenario
from skymule.sim.run import run_mission
from skymule.world import build_mission


def main() -> None:
    json_path = json_option()
    parser = argparse.ArgumentParser(description=__doc__)
    rows = []
    parser.add_argument("--repeat", type=int, default=size(50, 1))
    args = parser.parse_args()
    for preset in ("paper-sim-fixed", "aadm-default"):
        scenario = load_scenario(preset)
        start = time.perf_counter()
        mission = build_mission(scenario)
        build_s = time.perf_counter() - start
        for policy in ("greedy", "hgad"):
            spec = scenario.with_policy(policy).policy
            slots = 0
            start = time.perf_counter()
            for _ in range(args.repeat):
                slots += run_mission(mission, make_policy(spec)).n_slots
            elapsed = time.perf_counter() - start
            print(
                f"{preset:16s} {policy:7s} {slots / elapsed:10,.0f} slots/s "
                f"({elapsed / args.repeat * 1e3:.1f} ms per {slots // args.repeat}-slot mission; "
                f"build {build_s * 1e3:.1f} ms)"
            )
            per_ms = elapsed / args.repeat * 1e3
            rows.append([preset, policy, f"{slots / elapsed:,.0f}", f"{per_ms:.1f}"])
    columns = ["preset", "policy", "slots per s (wall)", "ms per mission (wall)"]
    write(json_path, {"single": table(columns, rows)})


if __name__ == "__main__":
    main()

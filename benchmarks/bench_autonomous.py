"""Autonomous missions: Greedy vs HGAD on paper-sim-autonomous, the Table II orders, speed.

Run: /work/venv/bin/python benchmarks/bench_autonomous.py
"""

from __future__ import annotations

import time

from skymule.metrics import summarize
from skymule.policies.hgad import HGAD
from skymule.runner import simulate
from skymule.scenario import load_scenario
from skymule.sim.run import run_mission
from skymule.world import build_mission

PRESET = "paper-sim-autonomous"
TABLE_II = [
    ((700, 500, 800, 1000), "LW4,LW3,LW1,LW2"),
    ((500, 800, 1000, 700), "LW3,LW2,LW4,LW1"),
    ((800, 500, 700, 1000), "LW4,LW1,LW3,LW2"),
    ((500, 1000, 700, 800), "LW2,LW4,LW3,LW1"),
]


def main() -> None:
    scenario = load_scenario(PRESET)
    mission = build_mission(scenario)
    print(f"{PRESET}: policy, Mbit, completion, hover s, distance m, energy kJ, AADM score, s/run")
    for name in ("greedy", "hgad"):
        start = time.perf_counter()
        s = simulate(scenario, name, mission=mission).summary
        took = time.perf_counter() - start
        print(
            f"  {name:6s} {s['total_downloaded_mbit']:7.1f} {s['completion']:.3f} "
            f"{s['hover_time_s']:5.0f} {s['distance_m']:6.0f} {s['energy_kj']:6.1f} "
            f"{s['aadm_score']:7.1f} {took:.3f}  order {','.join(s['visit_order'])}"
        )
    print("Table II (HGAD navigation order): buffers, paper, planned tour, by remaining data")
    for buffers, paper in TABLE_II:
        sensors = [
            sensor.model_copy(update={"buffer_mbit": float(b)})
            for sensor, b in zip(scenario.sensors, buffers, strict=True)
        ]
        case = build_mission(scenario.model_copy(update={"sensors": sensors}))
        orders = [
            ",".join(summarize(run_mission(case, HGAD(priority=p)), "t")["visit_order"])
            for p in ("initial", "remaining")
        ]
        print(f"  {buffers}  {paper}  {orders[0]} ({orders[0] == paper})  {orders[1]}")


if __name__ == "__main__":
    main()

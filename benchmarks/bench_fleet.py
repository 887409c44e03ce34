"""Several UAVs: the coordinated planner vs independent Greedy/HGAD/planner, with the K-UAV bound.

Random missions (seeded, :mod:`skymule.experiments.layouts` style): 4-8 sensors anywhere within
300 m of the Lake Wheeler fence, buffers 500-2000 Mbit, 200-400 s, 6-12 m/s, free space at
3.41 GHz (the paper-sim-autonomous radio), return home; K UAVs (default 2), each with its own
random home inside the fence. Every policy runs on the same missions; the K-UAV time-sharing
bound (:mod:`skymule.bounds.fleet`) caps them all. Prints, per policy, the mean download with
its 95 % confidence interval (normal approximation, 1.96 standard errors), the mean gap to
the bound, and the paired difference coordinated - independent HGAD with its 95 % CI and how
many missions coordinated wins.

Run: /work/venv/bin/python benchmarks/bench_fleet.py [--missions 100] [--uavs 2] [--workers 2]
Smoke test: /work/venv/bin/python benchmarks/bench_fleet.py --tiny
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from shapely.geometry import Point

from _results import json_option, write
from _results import table as results_table
from _sizes import size
from skymule.bounds.fleet import fleet_bound
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.scenario import Scenario, UavSpec, load_scenario
from skymule.sim.fleet import build_fleet
from skymule.tasks.fleet import simulate_fleet
from skymule.world import build_mission

PRESET = "paper-sim-autonomous"
SEED = 20261130
POLICIES = ("greedy", "hgad", "planner", "coordinated")
RANGES = LayoutRanges(n_sensors=(4, 8), buffer_mbit=(500.0, 2000.0), duration_s=(200, 400))
TINY = LayoutRanges(n_sensors=(3, 4), buffer_mbit=(300.0, 800.0), duration_s=(120, 160))


def fleet_scenario(
    rng: np.random.Generator, base: Scenario, uavs: int, ranges: LayoutRanges
) -> Scenario:
    """A random autonomous layout with ``uavs`` UAVs, each at its own random in-fence home."""
    scenario = random_autonomous_scenario(rng, base, ranges)
    fence = build_mission(scenario).fence
    assert fence is not None
    inner = fence.buffer(-2.0)
    minx, miny, maxx, maxy = fence.bounds
    specs = [UavSpec(name="U1", home=scenario.trajectory.home)]
    while len(specs) < uavs:
        home = rng.uniform([minx, miny], [maxx, maxy])
        if inner.covers(Point(home)):
            specs.append(UavSpec(name=f"U{len(specs) + 1}", home=[float(home[0]), float(home[1])]))
    return scenario.model_copy(update={"uavs": specs})


def evaluate(scenario: Scenario) -> list[float]:
    """[total buffer, download per policy in POLICIES..., bound] in Mbit."""
    fleet = build_fleet(scenario)
    row = [float(fleet.missions[0].buffers_bit.sum()) / 1e6]
    for policy in POLICIES:
        row.append(simulate_fleet(scenario, policy, fleet=fleet).summary["total_downloaded_mbit"])
    row.append(fleet_bound(fleet).upper_bound_bit / 1e6)
    return row


def mean_ci(values: np.ndarray) -> tuple[float, float]:
    """Mean and half-width of its 95 % confidence interval (1.96 standard errors)."""
    if len(values) < 2:
        return float(np.mean(values)), math.nan
    return float(np.mean(values)), 1.96 * float(np.std(values, ddof=1)) / math.sqrt(len(values))


def main(argv: list[str] | None = None) -> np.ndarray:
    json_path = json_option(argv)
    parser = argparse.ArgumentParser()
    parser.add_argument("--missions", type=int, default=100)
    parser.add_argument("--uavs", type=int, default=2)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument(
        "--tiny",
        action="store_true",
        default=size(False, True),
        help="<= 3 small missions (smoke test)",
    )
    args = parser.parse_args(argv)
    missions, ranges = (min(args.missions, 3), TINY) if args.tiny else (args.missions, RANGES)

    base = load_scenario(PRESET)
    rng = np.random.default_rng(args.seed)
    scenarios = [fleet_scenario(rng, base, args.uavs, ranges) for _ in range(missions)]
    if args.workers > 1 and not args.tiny:
        with ProcessPoolExecutor(args.workers) as pool:
            rows = list(pool.map(evaluate, scenarios))
    else:
        rows = [evaluate(s) for s in scenarios]
    table = np.asarray(rows)
    bound = table[:, -1]
    print(f"{missions} random missions, {args.uavs} UAVs, seed {args.seed}")
    print(f"{'policy':<14}{'mean Mbit':>11}{'95% CI':>10}{'gap to bound':>14}")
    rows: list[list[str]] = []
    for column, policy in enumerate(POLICIES, start=1):
        mean, half = mean_ci(table[:, column])
        gap = float(np.mean(bound - table[:, column]))
        print(f"{policy:<14}{mean:>11.1f}{'±' + format(half, '.1f'):>10}{gap:>14.1f}")
        rows.append([policy, f"{mean:.1f} ± {half:.1f}", f"{gap:.1f}"])
    print(f"{'bound':<14}{np.mean(bound):>11.1f}{'±' + format(mean_ci(bound)[1], '.1f'):>10}")
    rows.append(["bound", f"{np.mean(bound):.1f} ± {mean_ci(bound)[1]:.1f}", ""])
    diff = table[:, 1 + POLICIES.index("coordinated")] - table[:, 1 + POLICIES.index("hgad")]
    mean, half = mean_ci(diff)
    wins = int(np.sum(diff > 1e-6))
    print(
        f"coordinated - independent hgad: {mean:+.1f} ± {half:.1f} Mbit (95% CI); "
        f"coordinated ahead in {wins}/{missions} missions"
    )
    note = (
        f"{missions} random missions, {args.uavs} UAVs (seed {args.seed}); coordinated − "
        f"independent hgad: {mean:+.1f} ± {half:.1f} Mbit, ahead in {wins} of {missions}"
    )
    columns = ["policy", "mean Mbit ± 95% CI", "gap to bound [Mbit]"]
    write(json_path, {"fleet": results_table(columns, rows, note=note)})
    return table


if __name__ == "__main__":
    main()

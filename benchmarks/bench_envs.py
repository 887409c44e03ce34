"""Environment steps per second: the vectorised env vs stepping single envs, in one run.

Missions: random 4-sensor Lake Wheeler layouts (``skymule.experiments.layouts``) flown inside
the convex hull of the fence (kept so that the figures compare with earlier runs; the vector
env steps any fence: ``bench_vector_env.py`` measures Lake Wheeler's own, concave one), free
space, 200-450 s, return home. Actions are uniform random
(drawn before timing). The vector env steps ``--batch`` missions at once for ``--steps``
steps (autoreset included); the single envs (``skymule/DataMule-v0``, the engine core) step
the same missions one after another for ``--single-steps`` steps in all.

Run: python benchmarks/bench_envs.py [--batch 1024] [--steps 200] [--single-steps 3000]
Smoke test: python benchmarks/bench_envs.py --tiny
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _results import json_option, table, write
from _sizes import size
from skymule.envs.datamule import DataMuleEnv
from skymule.envs.vector import DataMuleVectorEnv
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.scenario import load_scenario
from skymule.world import Mission, build_mission, with_fence

SEED = 20251130
N_SENSORS = 4
DISTINCT = 32


def missions(count: int) -> list[Mission]:
    """``count`` missions cycling over DISTINCT random layouts in the fence's convex hull."""
    base = load_scenario("paper-sim-autonomous")
    fence = build_mission(base).fence
    assert fence is not None
    rng = np.random.default_rng(SEED)
    ranges = LayoutRanges(n_sensors=(N_SENSORS, N_SENSORS))
    distinct = [
        with_fence(build_mission(random_autonomous_scenario(rng, base, ranges)), fence.convex_hull)
        for _ in range(min(count, DISTINCT))
    ]
    return [distinct[i % len(distinct)] for i in range(count)]


def random_actions(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    serve = rng.integers(0, N_SENSORS + 1, shape)
    heading = rng.integers(0, 9, shape)
    return np.stack([serve, heading], axis=-1)


def vector_rate(batch: int, steps: int) -> float:
    env = DataMuleVectorEnv(missions(batch))
    env.reset(seed=0)
    actions = random_actions(np.random.default_rng(1), (steps, batch))
    start = time.perf_counter()
    for action in actions:
        env.step(action)
    return batch * steps / (time.perf_counter() - start)


def single_rate(total_steps: int) -> float:
    envs = [DataMuleEnv(m) for m in missions(DISTINCT)]
    for env in envs:
        env.reset(seed=0)
    actions = random_actions(np.random.default_rng(2), (total_steps,))
    start = time.perf_counter()
    for step, action in enumerate(actions):
        env = envs[step % len(envs)]
        _, _, done, _, _ = env.step(action)
        if done:
            env.reset()
    return total_steps / (time.perf_counter() - start)


def main() -> None:
    json_path = json_option()
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--batch", type=int, default=1024, help="missions in the vector env")
    parser.add_argument("--steps", type=int, default=200, help="vector steps")
    parser.add_argument("--single-steps", type=int, default=3000, help="single-env steps")
    parser.add_argument(
        "--tiny", action="store_true", default=size(False, True), help="smoke test: a few steps"
    )
    args = parser.parse_args()
    if args.tiny:
        args.batch, args.steps, args.single_steps = 16, 5, 20
    vector = vector_rate(args.batch, args.steps)
    single = single_rate(args.single_steps)
    print(f"{N_SENSORS} sensors, random Lake Wheeler layouts (convex hull of the fence)")
    print(f"vector env ({args.batch} missions): {vector:,.0f} env steps/s")
    print(f"single envs (engine core):      {single:,.0f} env steps/s")
    print(f"ratio: {vector / single:,.1f}x")
    rows = [
        [f"vector env ({args.batch} missions)", f"{vector:,.0f}", f"{vector / single:,.1f}"],
        ["single envs (engine core)", f"{single:,.0f}", "1.0"],
    ]
    columns = ["environment", "env steps per s", "ratio to single envs"]
    write(json_path, {"envs": table(columns, rows)})


if __name__ == "__main__":
    main()

"""Vector env steps per CPU second on Lake Wheeler's own (concave) fence, against single envs.

Missions: random 4-sensor Lake Wheeler layouts (``skymule.experiments.layouts``) on the real,
concave phase-1 fence, free space, 200-450 s, return home (the layouts of ``bench_envs.py``
without the convex hull). Actions: random serves and headings held for a while (drawn before
timing). The vector env (``skymule.envs.vector``) steps B missions at once, its path queries
in numpy (the navigator) or compiled (``CompiledPaths``, numba); the reference is 64 single
envs (``DataMule-v0``, the engine core) stepped in a loop, as a user without the vector env
would. CPU time (``time.process_time``): the machine is shared.

Run: python benchmarks/bench_vector_env.py [--batches 64,256] [--steps 500] [--single-steps 3000]
Smoke test: SKYMULE_BENCH_TINY=1 python benchmarks/bench_vector_env.py
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
from skymule.sim import compiled
from skymule.world import Mission, build_mission

SEED = 20251130
N_SENSORS = 4
DISTINCT = 32
SINGLES = 64
HEADING_CHANGE = 0.15


def missions(count: int) -> list[Mission]:
    """``count`` missions cycling over DISTINCT random layouts on the real fence."""
    base = load_scenario("paper-sim-autonomous")
    rng = np.random.default_rng(SEED)
    ranges = LayoutRanges(n_sensors=(N_SENSORS, N_SENSORS))
    distinct = [
        build_mission(random_autonomous_scenario(rng, base, ranges))
        for _ in range(min(count, DISTINCT))
    ]
    return [distinct[i % len(distinct)] for i in range(count)]


def random_actions(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """(steps, ..., 2) random serves and headings; each heading is held for a while (it
    changes with probability HEADING_CHANGE per step), so UAVs fly across the site and into
    the fence's corners as a policy that goes somewhere would (uniform headings each step
    keep them within a few hundred metres of home)."""
    serve = rng.integers(0, N_SENSORS + 1, shape)
    heading = rng.integers(0, 9, shape)
    change = rng.random(shape) < HEADING_CHANGE
    change[0] = True
    held = np.where(change, np.arange(shape[0]).reshape(-1, *[1] * (len(shape) - 1)), 0)
    last = np.maximum.accumulate(held, axis=0)  # the step each heading was last drawn
    heading = np.take_along_axis(heading, last, axis=0)
    return np.stack([serve, heading], axis=-1)


def vector_rate(batch: int, steps: int, engine: str) -> float:
    """Env steps per CPU second of the vector env (``engine``: numpy or compiled)."""
    env = DataMuleVectorEnv(missions(batch), engine=engine)  # type: ignore[arg-type]
    env.reset(seed=0)
    actions = random_actions(np.random.default_rng(1), (steps, batch))
    env.step(actions[0])  # compiles the kernels (once per process) outside the timing
    start = time.process_time()
    for action in actions[1:]:
        env.step(action)
    return batch * (steps - 1) / (time.process_time() - start)


def single_rate(total_steps: int) -> float:
    """Env steps per CPU second of SINGLES single envs stepped in a loop (about
    ``total_steps`` steps in all)."""
    envs = [DataMuleEnv(m) for m in missions(SINGLES)]
    for env in envs:
        env.reset(seed=0)
    rounds = max(total_steps // SINGLES, 1)
    actions = random_actions(np.random.default_rng(2), (rounds, SINGLES))
    start = time.process_time()
    for row in actions:
        for env, action in zip(envs, row, strict=True):
            _, _, done, _, _ = env.step(action)
            if done:
                env.reset()
    return rounds * SINGLES / (time.process_time() - start)


def main() -> None:
    json_path = json_option()
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--batches", default=size("64,256", "8"), help="vector env sizes")
    parser.add_argument("--steps", type=int, default=size(500, 4), help="vector steps")
    parser.add_argument("--single-steps", type=int, default=size(3000, 20), help="single steps")
    args = parser.parse_args()
    engines = ["numpy", "compiled"] if compiled.available() else ["numpy"]
    single = single_rate(args.single_steps)
    print(f"{N_SENSORS} sensors, random layouts on Lake Wheeler's concave fence, held headings")
    print(f"{SINGLES} single envs stepped in a loop: {single:,.0f} env steps/CPU-s")
    rows = [[f"{SINGLES} single envs in a loop", "", f"{single:,.0f}", "1.0"]]
    for batch in (int(b) for b in args.batches.split(",")):
        for engine in engines:
            rate = vector_rate(batch, args.steps, engine)
            print(
                f"vector env, {batch} missions, {engine} paths: {rate:,.0f} env steps/CPU-s "
                f"(ratio to single envs: {rate / single:,.1f}x)"
            )
            ratio = f"{rate / single:,.1f}"
            rows.append([f"vector env, {batch} missions", engine, f"{rate:,.0f}", ratio])
    columns = ["environment", "paths", "env steps per CPU-s", "ratio to single envs"]
    write(json_path, {"vector-env": table(columns, rows)})


if __name__ == "__main__":
    main()

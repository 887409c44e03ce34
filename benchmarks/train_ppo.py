"""Train a small PPO agent on random Lake Wheeler missions and compare it honestly.

Training: ``skymule/DataMule-v0`` (headings, scaled observation, reward = Mbit per slot) on a
new random autonomous mission at every reset (4 sensors within 300 m of the Lake Wheeler fence,
buffers 300-1500 Mbit, 200-450 s, random home, 6-12 m/s, free space: the layouts of
``benchmarks/bench_planner.py`` with 4 sensors), stable-baselines3 PPO on the CPU, stopped at
``--timesteps`` or ``--minutes`` of wall time, whichever comes first. Rewards are normalised for
training only (VecNormalize); the agent sees the fixed-scale observation the ``rl:`` policy
builds, so the saved model runs as ``--policy rl:MODEL.zip``.

Evaluation: 200 held-out missions (another seed) under the trained agent (as an ``rl:``
policy on the engine), Greedy, HGAD, the planner and the autonomous upper bound; mean download
with a 95% confidence interval (normal approximation, 1.96 standard errors) and the mean gap
to the bound; printed as a Markdown table whatever the outcome.

Run: python benchmarks/train_ppo.py --minutes 20 --out runs/ppo_lake_wheeler.zip
Smoke test: python benchmarks/train_ppo.py --tiny --out /tmp/ppo_tiny.zip
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from _results import json_option, table, write
from _sizes import size
from skymule.bounds.autonomous import autonomous_bound
from skymule.envs.datamule import DataMuleEnv
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.policies import HGAD, Greedy
from skymule.policies.planner import Planner
from skymule.policies.rl import RLPolicy
from skymule.scenario import Scenario, load_scenario
from skymule.sim.run import run_mission
from skymule.trust import trusting
from skymule.world import build_mission

PRESET = "paper-sim-autonomous"
RANGES = LayoutRanges(n_sensors=(4, 4))
TRAIN_SEED = 7
HELD_OUT_SEED = 20250601


def layout_generator(base: Scenario) -> Callable[[np.random.Generator], Scenario]:
    """rng -> a random 4-sensor Lake Wheeler mission (for the env's resets)."""

    def draw(rng: np.random.Generator) -> Scenario:
        return random_autonomous_scenario(rng, base, RANGES)

    return draw


def train(args: argparse.Namespace, base: Scenario) -> tuple[Path, int, float]:
    """Train PPO; returns (model path, timesteps trained, wall seconds)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    class WallClock(BaseCallback):
        def __init__(self, seconds: float) -> None:
            super().__init__()
            self.deadline = time.monotonic() + seconds

        def _on_step(self) -> bool:
            return time.monotonic() < self.deadline

    def make(rank: int) -> Callable[[], DataMuleEnv]:
        def build() -> DataMuleEnv:
            env = DataMuleEnv(layout_generator(base), scaled=True)
            env.reset(seed=TRAIN_SEED * 1000 + rank)
            return env

        return build

    torch.set_num_threads(1)  # a 64x64 MLP: threads cost more than they give on 2 busy cores
    venv = VecNormalize(
        DummyVecEnv([make(rank) for rank in range(args.envs)]), norm_obs=False, norm_reward=True,
        gamma=args.gamma,
    )  # fmt: skip
    venv.seed(TRAIN_SEED)
    model = PPO(
        "MlpPolicy", venv, n_steps=args.n_steps, batch_size=256, n_epochs=5, gamma=args.gamma,
        learning_rate=3e-4, ent_coef=0.01, policy_kwargs={"net_arch": [64, 64]}, seed=TRAIN_SEED,
        device="cpu", verbose=0,
    )  # fmt: skip
    start = time.perf_counter()
    model.learn(total_timesteps=args.timesteps, callback=WallClock(args.minutes * 60.0))
    took = time.perf_counter() - start
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    model.save(str(out))
    return out, int(model.num_timesteps), took


def baselines(scenario: Scenario) -> tuple[float, float, float, float, float]:
    """(total buffered, greedy, hgad, planner, bound) [bit] of one mission."""
    mission = build_mission(scenario)
    got = [float(run_mission(mission, p).downloaded_bit.sum()) for p in (Greedy(), HGAD())]
    planner = float(run_mission(mission, Planner()).downloaded_bit.sum())
    bound = autonomous_bound(mission).upper_bound_bit
    return float(mission.buffers_bit.sum()), got[0], got[1], planner, bound


def rl_downloads(model_path: Path, scenarios: list[Scenario]) -> np.ndarray:
    with trusting([model_path]):  # the model this script has just trained
        policy = RLPolicy(f"rl:{model_path}")
    return np.array(
        [float(run_mission(build_mission(s), policy).downloaded_bit.sum()) for s in scenarios]
    )


def mean_ci(values: np.ndarray) -> tuple[float, float]:
    """Mean and 95% half-width (1.96 standard errors)."""
    half = 1.96 * values.std(ddof=1) / np.sqrt(len(values)) if len(values) > 1 else float("nan")
    return float(values.mean()), float(half)


def main() -> None:
    json_path = json_option()
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--out",  # the tiny smoke run never writes over the committed model
        default=size(
            "runs/ppo_lake_wheeler.zip", str(Path(tempfile.gettempdir()) / "ppo_tiny.zip")
        ),
    )
    parser.add_argument("--minutes", type=float, default=25.0, help="wall-time training budget")
    parser.add_argument("--timesteps", type=int, default=5_000_000)
    parser.add_argument("--envs", type=int, default=4)
    parser.add_argument("--n-steps", type=int, default=512)
    parser.add_argument("--gamma", type=float, default=0.995)
    parser.add_argument("--missions", type=int, default=200, help="held-out missions")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--tiny",
        action="store_true",
        default=size(False, True),
        help="smoke test: seconds, 4 missions",
    )
    args: Any = parser.parse_args()
    if args.tiny:
        args.minutes, args.timesteps, args.missions, args.n_steps = 0.2, 1024, 4, 128

    base = load_scenario(PRESET)
    path, steps, took = train(args, base)
    print(f"trained {steps} env steps in {took:.0f} s ({steps / took:.0f} steps/s) -> {path}")

    rng = np.random.default_rng(HELD_OUT_SEED)
    scenarios = [random_autonomous_scenario(rng, base, RANGES) for _ in range(args.missions)]
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        rows = np.array(list(pool.map(baselines, scenarios, chunksize=4)))
    rl = rl_downloads(path, scenarios)
    print(f"evaluated {args.missions} held-out missions in {time.perf_counter() - start:.0f} s")
    total, greedy, hgad, planner, bound = rows.T
    print(f"\nmean total buffered: {total.mean() / 1e6:.1f} Mbit")
    print("| policy | mean download [Mbit] | 95% CI | mean gap to bound |")
    print("|---|---:|---:|---:|")
    found = []
    for name, values in (
        ("PPO (rl:)", rl), ("greedy", greedy), ("hgad", hgad), ("planner", planner),
        ("bound", bound),
    ):  # fmt: skip
        mean, half = mean_ci(values / 1e6)
        gap = float(np.mean((bound - values) / bound))
        print(f"| {name} | {mean:.1f} | ± {half:.1f} | {gap:.1%} |")
        found.append([name, f"{mean:.1f}", f"± {half:.1f}", f"{gap:.1%}"])
    paired = (rl - hgad) / 1e6
    mean, half = mean_ci(paired)
    print(f"\nPPO - HGAD per mission: {mean:+.1f} ± {half:.1f} Mbit; PPO ahead in "
          f"{int((rl > hgad).sum())} of {len(rl)}")  # fmt: skip
    note = (
        f"{args.missions} held-out missions; PPO - HGAD per mission: {mean:+.1f} ± {half:.1f} "
        f"Mbit, PPO ahead in {int((rl > hgad).sum())} of {len(rl)}"
    )
    columns = ["policy", "mean download [Mbit]", "95% CI", "mean gap to bound"]
    write(json_path, {"train-ppo": table(columns, found, note=note, align="lrrr")})


if __name__ == "__main__":
    main()

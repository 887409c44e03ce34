"""Train the ``learned`` option scorer on the engine and write its weights (npz) and curve.

Reproduces the shipped model (``src/skymule/data/learned_policy.npz``):

    nice python benchmarks/train_learned.py --minutes 28 > train.log

Evolution strategies (:mod:`learning.es`, numpy only, ``--workers`` processes) on
random Lake Wheeler missions with 3..8 sensors, random channels and faults
(:mod:`learning.missions`). Every ``--validate-every`` generations the current model
flies 64 four-sensor and 32 eight-sensor validation missions (their own seed, not the
benchmark's held-out one) against HGAD; the best validated model is kept. Writes the weights,
the learning curve as CSV (``--curve``) and its figure (``--figure``, drawn from the CSV).

``--algorithm ppo`` trains the same network on the same options with PPO instead
(:mod:`learning.ppo`, needs torch: the ``rl`` extra) for the measured comparison:

    nice python benchmarks/train_learned.py --algorithm ppo --minutes 10 --out /tmp/ppo.npz
    nice python benchmarks/train_learned.py --algorithm es --minutes 10 --out /tmp/es.npz

Smoke test: SKYMULE_BENCH_TINY=1 python benchmarks/train_learned.py (seconds; writes to the
temporary folder, never over the shipped model). ``--json PATH``: the kept model's validation
figures as a table (``train-learned``).
"""

from __future__ import annotations

import argparse
import csv
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from _results import json_option, table, write
from _sizes import size
from learning.es import ESConfig, fitness, reference_downloads, relative_gain, train_es
from learning.missions import HELD_OUT, draw_missions
from skymule.io.atomic import atomic_path, write_with
from skymule.policies.learned import LearnedPolicy, OptionNet, load_net, save_net
from skymule.sim.run import run_missions

VALIDATION_SEED = 11
TINY_ES: dict[str, Any] = {
    "pairs": 2, "missions_per_count": 2, "pool_per_count": 3, "sensor_counts": (3, 4),
}  # fmt: skip
ROOT = Path(__file__).resolve().parents[1]
TMP = Path(tempfile.gettempdir())


def validator(counts: dict[int, int], teacher: str = "hgad") -> Any:
    """validate(net) -> figures: mean and worst gain over the reference (HGAD, or the
    planner with ``--teacher planner``) per sensor count, and the score that picks the kept
    model (the training fitness over all validation missions)."""
    sets = {n: draw_missions(VALIDATION_SEED, n, k, HELD_OUT) for n, k in counts.items()}
    reference = {n: reference_downloads(m, teacher) for n, m in sets.items()}

    def validate(net: OptionNet) -> dict[str, float]:
        figures: dict[str, float] = {}
        gains = []
        for n, missions in sets.items():
            bits = run_missions(missions, LearnedPolicy(net), detail=False).downloaded_bit
            gain = relative_gain(bits.sum(axis=1), reference[n])
            figures[f"gain_{n}"] = float(gain.mean())
            figures[f"worst_{n}"] = float(gain.min())
            gains.append(gain)
        shipped = ESConfig()  # the kept model is scored as training scores members
        score = fitness(np.concatenate(gains)[None], shipped.loss_margin, shipped.loss_weight)
        figures["score"] = float(score[0])
        return figures

    return validate


def write_curve(rows: list[dict[str, float]], path: Path) -> None:
    """The learning curve as CSV (atomically)."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]) if rows else ["generation"])
        writer.writeheader()
        writer.writerows(rows)


def plot_curve(csv_path: Path, figure: Path) -> None:
    """The learning curve figure, read from its CSV."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    curve = pd.read_csv(csv_path)
    fig, ax = plt.subplots(figsize=(6.4, 3.6), layout="constrained")
    minutes = curve["seconds"] / 60.0
    for column, label in (
        ("gain_4", "4 sensors, mean"), ("gain_8", "8 sensors, mean"),
        ("worst_4", "4 sensors, worst mission"),
    ):  # fmt: skip
        if column in curve:
            ax.plot(minutes, 100 * curve[column], label=label)
    ax.axhline(0.0, color="black", lw=0.8)
    ax.set_xlabel("training wall time [min] (2 cores)")
    ax.set_ylabel("download vs HGAD [%]")
    ax.set_title("learned: validation missions (300 s, Lake Wheeler)")
    ax.legend(fontsize=8)
    write_with(figure, lambda tmp: fig.savefig(tmp, dpi=120, format="png"))
    plt.close(fig)


def main() -> None:
    json_path = json_option()
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--algorithm", choices=("es", "ppo"), default="es")
    parser.add_argument("--minutes", type=float, default=size(28.0, 5.0))
    parser.add_argument(
        "--out",
        default=size(
            str(ROOT / "src/skymule/data/learned_policy.npz"), str(TMP / "learned_tiny.npz")
        ),
    )
    parser.add_argument(
        "--curve",
        default=size(str(ROOT / "docs/figures/learned_curve.csv"), str(TMP / "learned_tiny.csv")),
    )
    parser.add_argument(
        "--figure",
        default=size(str(ROOT / "docs/figures/learned_curve.png"), str(TMP / "learned_tiny.png")),
    )
    parser.add_argument("--workers", type=int, default=size(2, 1))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--validate-every", type=int, default=size(10, 1))
    parser.add_argument(
        "--teacher",
        choices=("hgad", "planner"),
        default="hgad",
        help="the reference of the fitness and the validation (es only)",
    )
    parser.add_argument("--start", help="weights (.npz) to fine-tune instead of a new model (es)")
    parser.add_argument("--pairs", type=int, help="antithetic pairs per generation (es)")
    parser.add_argument("--missions-per-count", type=int, help="missions per generation (es)")
    parser.add_argument("--pool", type=int, help="training missions per sensor count (es)")
    parser.add_argument("--sigma", type=float, help="perturbation scale (es)")
    parser.add_argument("--learning-rate", type=float, help="Adam step (es)")
    args = parser.parse_args()
    tiny = size(False, True)
    validate = validator({4: 4, 8: 2} if tiny else {4: 64, 8: 32}, args.teacher)
    seconds = args.minutes * 60.0
    start = time.monotonic()
    if args.algorithm == "es":
        chosen: dict[str, Any] = {
            "pairs": args.pairs,
            "missions_per_count": args.missions_per_count,
            "pool_per_count": args.pool,
            "sigma": args.sigma,
            "learning_rate": args.learning_rate,
        }
        config = ESConfig(
            seed=args.seed,
            workers=args.workers,
            teacher=args.teacher,
            **(TINY_ES if tiny else {}) | {k: v for k, v in chosen.items() if v is not None},
        )
        result = train_es(
            config,
            seconds,
            validate,
            args.validate_every,
            max_generations=size(None, 2),
            start_net=None if args.start is None else load_net(args.start),
        )
        net, curve = result.net, result.curve
        print(
            f"es: {result.generations} generations, {result.missions_flown:,} missions flown "
            f"in {result.seconds:.0f} s"
        )
    else:
        from learning.ppo import PPOConfig, train_ppo

        tiny_ppo: dict[str, Any] = {
            "missions_per_batch": 3, "pool_per_count": 3, "sensor_counts": (3, 4),
        }  # fmt: skip
        config_ppo = PPOConfig(seed=args.seed, **(tiny_ppo if tiny else {}))
        result_ppo = train_ppo(
            config_ppo, seconds, validate, args.validate_every, max_iterations=size(None, 2)
        )
        net, curve = result_ppo.net, result_ppo.curve
        print(
            f"ppo: {result_ppo.iterations} iterations, {result_ppo.missions_flown:,} missions "
            f"flown in {result_ppo.seconds:.0f} s"
        )
    out = save_net(net, args.out)
    final = validate(net)
    print(f"trained {args.algorithm} in {time.monotonic() - start:.0f} s -> {out}")
    print("validation of the kept model: " + "  ".join(f"{k} {v:+.4f}" for k, v in final.items()))
    rows = [[name, f"{value:+.4f}"] for name, value in final.items()]
    note = f"{args.algorithm}, {time.monotonic() - start:.0f} s wall, weights: {out}"
    write(json_path, {"train-learned": table(["validation", "value"], rows, note=note)})
    if curve:
        write_curve(curve, Path(args.curve))
        plot_curve(Path(args.curve), Path(args.figure))
        print(f"learning curve: {args.curve}, {args.figure}")


if __name__ == "__main__":
    main()

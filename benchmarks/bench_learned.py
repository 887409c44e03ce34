"""The shipped ``learned`` policy against Greedy, HGAD, the planner and the upper bound.

Held-out random Lake Wheeler missions (seed 20250601, never trained or validated on): 300 s,
free space, buffers of 300-1500 Mbit per sensor that the UAV cannot empty, for 3, 4, 6 and 8
sensors, without faults and with faults (one random outage per tower, mean 60 s, and a 6 dB
SNR measurement error). Per condition and sensor count: mean download with a 95% confidence
interval (1.96 standard errors), the mean gap to the autonomous upper bound (fault-free: an
upper bound with faults too), and learned minus each other policy per mission (paired
difference, 95% CI), learned's mean and worst mission relative to HGAD and how many missions
it loses to HGAD by more than 5%. Then the speed: one decision of one mission (inference,
features included) and the batched form inside the engine.

    python benchmarks/bench_learned.py                 # 200 missions per row (~20 min)
    python benchmarks/bench_learned.py --missions 50 --counts 4

``--json PATH`` (``benchmarks/results/learned.json``) writes the table of docs/learning.md,
the speed as its note.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from _results import json_option, table, write
from _sizes import size
from learning.missions import HELD_OUT, HELD_OUT_FAULTS, draw_missions
from skymule.bounds.autonomous import autonomous_bound
from skymule.policies import HGAD, Greedy
from skymule.policies.learned import LearnedPolicy, load_net, shipped_weights
from skymule.policies.planner import Planner
from skymule.sim import compiled
from skymule.sim.run import run_mission, run_missions
from skymule.world import Mission

HELD_OUT_SEED = 20250601
CONDITIONS = {"none": HELD_OUT, "faults": HELD_OUT_FAULTS}


def planner_and_bound(mission: Mission) -> tuple[float, float]:
    """(planner's download, upper bound) [bit] of one mission."""
    planner = float(run_mission(mission, Planner()).downloaded_bit.sum())
    return planner, float(autonomous_bound(mission).upper_bound_bit)


def mean_ci(values: np.ndarray) -> tuple[float, float]:
    """Mean and 95% half-width (1.96 standard errors)."""
    half = 1.96 * values.std(ddof=1) / np.sqrt(len(values)) if len(values) > 1 else 0.0
    return float(values.mean()), float(half)


def totals(missions: list[Mission], workers: int) -> dict[str, np.ndarray]:
    """Bits downloaded per mission by every policy, and the bound."""
    net = load_net(shipped_weights())
    out = {
        "learned": run_missions(missions, LearnedPolicy(net), detail=False).downloaded_bit,
        "greedy": run_missions(missions, Greedy(), detail=False).downloaded_bit,
        "hgad": run_missions(missions, HGAD(), detail=False).downloaded_bit,
    }
    got = {name: bits.sum(axis=1) for name, bits in out.items()}
    with ProcessPoolExecutor(workers) as pool:
        rows = np.array(list(pool.map(planner_and_bound, missions, chunksize=4)))
    got["planner"], got["bound"] = rows[:, 0], rows[:, 1]
    return got


def report(condition: str, n: int, got: dict[str, np.ndarray]) -> list[str]:
    """Print one block and its ``row:`` lines; return its row of the docs' table."""
    cells: dict[str, str] = {}
    bound = got["bound"]
    learned = got["learned"]
    hgad = got["hgad"]
    label = "with" if condition == "faults" else "without"
    buffered = got["buffered"].mean() / 1e6
    print(f"\n{label} faults, {n} sensors, {len(learned)} missions ({buffered:.1f} Mbit buffered):")
    print("  policy    mean Mbit ± 95% CI   gap to bound   learned - policy [Mbit] ± 95% CI")
    for name in ("learned", "greedy", "hgad", "planner", "bound"):
        mean, half = mean_ci(got[name] / 1e6)
        gap = float(np.mean((bound - got[name]) / bound))
        diff, diff_half = mean_ci((learned - got[name]) / 1e6)
        print(
            f"  {name:8s} {mean:8.1f} ± {half:5.1f}   {gap:6.1%}   {diff:+8.1f} ± {diff_half:5.1f}"
        )
        cells[name] = f"{mean:.1f} ± {half:.1f}"
        cells[f"diff {name}"] = f"{diff:+.1f} ± {diff_half:.1f}"
        cells[f"gap {name}"] = f"{100 * gap:.1f}%"
        print(
            f"row: condition={condition} n={n} policy={name} mean={mean:.1f} ci={half:.1f} "
            f"gap={gap:.4f} diff={diff:.1f} diff_ci={diff_half:.1f}"
        )
    relative = (learned - hgad) / hgad
    rel_mean, rel_half = mean_ci(relative)
    below = int((relative < -0.05).sum())
    print(
        f"  learned vs hgad: {rel_mean:+.2%} ± {rel_half:.2%} per mission, worst "
        f"{relative.min():+.2%}, ahead in {int((learned > hgad).sum())} of {len(learned)}, "
        f"more than 5% below in {below}"
    )
    print(
        f"vs-hgad: condition={condition} n={n} rel={rel_mean:.4f} rel_ci={rel_half:.4f} "
        f"worst={relative.min():.4f} below5={below} ahead={int((learned > hgad).sum())} "
        f"missions={len(learned)}"
    )
    return [
        "faults" if condition == "faults" else "none",
        str(n),
        str(len(learned)),
        *(cells[name] for name in ("learned", "greedy", "hgad", "planner", "bound")),
        cells["diff hgad"],
        f"{100 * rel_mean:+.1f}% ± {100 * rel_half:.1f}",
        f"{100 * relative.min():+.1f}%, {below}",
        cells["diff planner"],
        cells["gap learned"],
    ]


COLUMNS = [
    "faults", "N", "missions", "learned", "greedy", "hgad", "planner", "bound",
    "learned − hgad", "vs hgad", "worst vs hgad, missions < −5%", "learned − planner",
    "learned's gap to bound",
]  # fmt: skip


def speed(missions: list[Mission], repeat: int) -> str:
    """Inference per decision (one mission) and the batched form in the engine; returns the
    table's note."""
    net = load_net(shipped_weights())
    one = missions[0]
    policy = LearnedPolicy(net)
    run_mission(one, policy)  # warm up (compiled paths)
    chosen = {"seconds": 0.0, "decisions": 0}
    for _ in range(repeat):
        policy = LearnedPolicy(net)
        original = policy.choose

        def timed(decision: object, original: object = original) -> np.ndarray:
            start = time.process_time()
            choice = original(decision)  # type: ignore[operator]
            chosen["seconds"] += time.process_time() - start
            chosen["decisions"] += len(decision.rows)  # type: ignore[attr-defined]
            return choice

        policy.choose = timed  # type: ignore[method-assign]
        run_mission(one, policy)
    per_us = 1e6 * chosen["seconds"] / max(chosen["decisions"], 1)
    print(f"\ninference, one mission: {per_us:.1f} us CPU per decision (features + network; "
          f"target <= 50), {chosen['decisions']} decisions")  # fmt: skip
    batch = [missions[i % len(missions)] for i in range(size(1024, 16))]
    policy = LearnedPolicy(net)
    start = time.process_time()
    flights = run_missions(batch, policy, detail=False)
    cpu = cpu_batch = time.process_time() - start
    assert policy.runner is not None
    slots = int(flights.n_run.sum())
    decided = policy.runner.decisions  # the batch's (reset below starts a new runner)
    print(
        f"batched in the engine, {len(batch)} missions: {policy.runner.decisions / cpu:,.0f} "
        f"decisions per CPU-s ({slots / cpu:,.0f} mission-slots per CPU-s, engine included; "
        f"{policy.runner.decisions / len(batch):.1f} decisions per mission)"
    )
    # the scorer alone on a batch of decisions (every mission deciding at its start)
    from skymule.policies.learned import compiled_scores, scores
    from skymule.sim.autonomous import AutonomousEngine

    engine = AutonomousEngine(batch, detail=False)
    seen = engine.observe()
    policy.reset(engine.contexts())
    assert policy.runner is not None
    rows = np.arange(len(batch))
    here = np.asarray(seen.position_m[:, :2], float)
    decision = policy.runner.decision(rows, here, seen.slot, seen.remaining_bit, seen.rate_bps)
    forms = {"numpy": lambda: scores(net, None, decision)}
    rates = {}
    if compiled.available():  # what LearnedPolicy runs with numba installed
        forms["compiled"] = lambda: compiled_scores(net, decision)
        forms["compiled"]()  # compile (or load from the cache) outside the timing
    for form, score in forms.items():
        start = time.process_time()
        for _ in range(repeat):
            np.argmax(score(), axis=1)
        cpu = time.process_time() - start
        rates[form] = repeat * len(batch) / cpu
        print(
            f"scorer on a batch of {len(batch)} decisions ({form}): "
            f"{repeat * len(batch) / cpu:,.0f} decisions per CPU-s"
        )
    start = time.process_time()
    run_missions(batch, HGAD(), detail=False)
    hgad_rate = slots / (time.process_time() - start)
    print(f"  hgad in the same engine: {hgad_rate:,.0f} mission-slots per CPU-s")
    twin = f", its compiled twin {rates['compiled']:,.0f}" if "compiled" in rates else ""
    return (
        f"Speed (same run): one decision of one mission (features and network) {per_us:.1f} µs "
        f"CPU; batched in the engine {decided / cpu_batch:,.0f} option decisions "
        f"per CPU-s, i.e. {slots / cpu_batch:,.0f} mission-slots (a serve and a goal each) per "
        f"CPU-s, engine included (HGAD {hgad_rate:,.0f}), "
        f"{decided / len(batch):.1f} decisions per mission; the scorer alone on "
        f"a batch of {len(batch)} decisions {rates['numpy']:,.0f} decisions per CPU-s "
        f"(numpy){twin} (`python benchmarks/bench_learned.py`)."
    )


def main() -> None:
    json_path: Path | None = json_option()
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--missions", type=int, default=size(200, 3))
    parser.add_argument("--counts", default=size("3,4,6,8", "3,4"))
    parser.add_argument("--conditions", default="none,faults")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    counts = [int(c) for c in args.counts.split(",")]
    start = time.perf_counter()
    first: list[Mission] = []
    rows = []
    for condition in args.conditions.split(","):
        for n in counts:
            missions = draw_missions(HELD_OUT_SEED, n, args.missions, CONDITIONS[condition])
            first = first or missions
            got = totals(missions, args.workers)
            got["buffered"] = np.array([m.buffers_bit.sum() for m in missions])
            rows.append(report(condition, n, got))
    print(f"\n(evaluation {time.perf_counter() - start:.0f} s wall)")
    note = speed(first, size(20, 2))
    write(json_path, {"learned": table(COLUMNS, rows, note=note)})


if __name__ == "__main__":
    main()

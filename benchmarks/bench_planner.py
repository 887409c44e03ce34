"""Planner vs HGAD over random autonomous missions, with the autonomous upper bound.

Random missions (seeded): 3-6 sensors anywhere within 300 m of the Lake Wheeler fence, buffers
300-1500 Mbit, 200-450 s, home at a random in-fence point, 6-12 m/s, free space at 3.41 GHz
(the paper-sim-autonomous radio), return home. Prints the mean and worst-case gain of planner
over HGAD, how many missions it loses by more than 1 %, the mean gap to the bound (geodesic
reach, the default, and the straight-line reach it tightens), the bound's run time, and the
preset's time-to-complete / AADM score.

Run: python benchmarks/bench_planner.py [--missions 200] [--workers 2]
(SKYMULE_BENCH_TINY=1: 3 missions in this process, no variants of the preset)

Speed only: /work/venv/bin/python benchmarks/bench_planner.py --speed 20 [--before main]
prints planner missions per CPU-second of the planner at git revision ``--before`` (its
planner.py, loaded from git) and of this one (with the compiled look-ahead, and with the same
look-ahead as plain Python, as without numba), on the preset plus random missions, the ratios,
and whether every mission's log is identical to before (same plans, slot for slot).

``--json PATH``: with ``--speed``, the speed table's planner row (``speed-planner``,
``benchmarks/results/planner.json``, docs/speed.md); otherwise the random missions' figures
(``planner-random``).
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from _results import json_option, table, write
from _sizes import size
from skymule.bounds.autonomous import autonomous_bound
from skymule.experiments.layouts import random_autonomous_scenario
from skymule.metrics.flights import MissionLog
from skymule.metrics.summary import aadm_score, completion_time_s
from skymule.policies import HGAD
from skymule.policies import planner as planner_module
from skymule.policies.planner import Planner
from skymule.scenario import Scenario, load_scenario
from skymule.sim import plans
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


def planner_at(revision: str) -> type[Planner]:
    """The Planner class of ``policies/planner.py`` at git ``revision``."""
    source = subprocess.run(
        ["git", "show", f"{revision}:src/skymule/policies/planner.py"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as handle:
        handle.write(source)
    spec = importlib.util.spec_from_file_location("planner_before", handle.name)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["planner_before"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module.Planner  # type: ignore[no-any-return]


def same_log(a: MissionLog, b: MissionLog) -> bool:
    """Every per-slot field of two logs equal (positions, SNR, served, bits, buffers ...)."""
    fields = ("position_m", "end_position_m", "snr_db", "rate_bps", "served", "downloaded_bit",
              "remaining_bit", "hovering", "target")  # fmt: skip
    return a.n_slots == b.n_slots and all(
        np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True) for f in fields
    )


def speed(n_missions: int, revision: str, json_path: Path | None = None) -> None:
    """Planner missions per CPU-second, before (``revision``) and now; identical logs?"""
    base = load_scenario(PRESET)
    rng = np.random.default_rng(SEED)
    scenarios = [base, *(random_autonomous_scenario(rng, base) for _ in range(n_missions - 1))]
    missions = [build_mission(s) for s in scenarios]
    run_mission(missions[0], Planner())  # compile (or load) the batched look-ahead first
    before_cls = planner_at(revision)
    seconds, logs = {}, {}
    compiled_kernel = planner_module.plans_kernel
    for label, cls, kernel in (
        ("before", before_cls, compiled_kernel),
        ("now", Planner, compiled_kernel),
        ("now, plain Python look-ahead (no numba)", Planner, lambda: plans.simulate_plans),
    ):
        planner_module.plans_kernel = kernel  # type: ignore[assignment]
        start = time.process_time()
        logs[label] = [run_mission(m, cls()) for m in missions]
        seconds[label] = time.process_time() - start
    planner_module.plans_kernel = compiled_kernel  # type: ignore[assignment]
    before = logs.pop("before")
    rates = {label: n_missions / s for label, s in seconds.items()}
    print(f"planner on {n_missions} missions ({PRESET} + random), missions per CPU-second:")
    before_rate = rates.pop("before")
    print(f"  before ({revision}): {before_rate:.2f}")
    identical = {}
    for label, rate in rates.items():
        same = sum(same_log(a, b) for a, b in zip(before, logs[label], strict=True))
        identical[label] = same
        print(
            f"  {label}: {rate:.2f}  x{rate * seconds['before'] / n_missions:.1f}, "
            f"identical logs: {same} of {n_missions}"
        )
    now, plain = rates["now"], rates["now, plain Python look-ahead (no numba)"]
    row = [
        "planner (autonomous), look-ahead batched and compiled",
        f"{now:.1f} missions per CPU-s ({revision} in the same run: {before_rate:.1f}, "
        f"×{now / before_rate:.1f}; {plain:.1f} without numba); identical plans in "
        f"{identical['now']} of {n_missions} missions",
        f"`python benchmarks/bench_planner.py --speed {n_missions} --before {revision}`",
    ]
    write(json_path, {"speed-planner": table(["what", "figure", "command"], [row], align="lll")})


def main() -> None:
    json_path = json_option()
    parser = argparse.ArgumentParser()
    parser.add_argument("--missions", type=int, default=size(200, 3))
    parser.add_argument("--workers", type=int, default=size(2, 1))
    parser.add_argument("--speed", type=int, default=0, help="only the speed comparison")
    parser.add_argument("--before", default="main", help="git revision to compare with")
    args = parser.parse_args()
    if args.speed:
        speed(args.speed, args.before, json_path)
        return

    base = load_scenario(PRESET)
    mission = build_mission(base)
    print(f"{PRESET} (all 3000 Mbit fit): policy, Mbit, time to complete s, AADM score")
    for policy in (HGAD(), Planner()):
        log = run_mission(mission, policy)
        print(
            f"  {policy.name:8s} {log.downloaded_bit.sum() / 1e6:7.1f} "
            f"{completion_time_s(log)!s:>6} {aadm_score(log):7.1f}"
        )
    variants = (
        ("300 s", {"mission": base.mission.model_copy(update={"duration_s": 300.0})}),
        (
            "1500 Mbit each",
            {"sensors": [s.model_copy(update={"buffer_mbit": 1500.0}) for s in base.sensors]},
        ),
    )
    for label, changes in variants[: size(2, 0)]:
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
    if args.workers == 1:  # no pool to start (tiny-size mode, or a machine with one core)
        rows = np.array([evaluate(s) for s in scenarios])
    else:
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
    figures = [
        ["missions", f"{args.missions}"],
        ["bound below the total buffer", f"{(bound < total * (1 - 1e-9)).sum()}"],
        ["planner gain over hgad, mean", f"{gain.mean():+.1%}"],
        ["planner gain over hgad, median", f"{np.median(gain):+.1%}"],
        ["planner gain over hgad, best", f"{gain.max():+.1%}"],
        ["planner gain over hgad, worst", f"{gain.min():+.1%}"],
        ["missions with planner behind hgad", f"{(gain < -1e-9).sum()}"],
        ["missions with planner behind hgad by > 1%", f"{(gain < -0.01).sum()}"],
        ["mean gap to bound, hgad", f"{((bound - hgad) / bound).mean():.1%}"],
        ["mean gap to bound, planner", f"{gap.mean():.1%}"],
        ["missions with a policy above the bound", f"{above.sum()}"],
        ["planner run time per mission, mean [s]", f"{took.mean():.1f}"],
    ]
    write(json_path, {"planner-random": table(["figure", "value"], figures, align="lr")})


if __name__ == "__main__":
    main()

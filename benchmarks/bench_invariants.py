"""Random missions with faults on, every invariant of the slot contract checked (issue 15).

Run: python benchmarks/bench_invariants.py [--missions 10000] [--seed 0]
(SKYMULE_BENCH_TINY=1: 8 missions)

Each mission is drawn from a seeded generator: fixed (paper-sim-fixed) or autonomous (a random
Lake Wheeler layout, skymule.experiments.layouts), random buffers, a random policy (greedy,
hgad, hgad-robust) and one to three random faults (outage, gilbert-elliott, snr-error,
missed-polls, gps-error, wind). Checked on every log:

* downloads never exceed a buffer and buffers never go negative;
* at most one sensor loses data per slot, and only the served one;
* every download is min(true rate x dt, data left), or 0 where a fault blocked it;
* autonomous: the UAV stays inside the geofence and under the speed cap, and ends at home --
  with wind too (the engine times the way home at the ground speed the wind allows; windy
  missions are also counted on their own line). A mission whose wind is at least the UAV's
  speed could never get home once it left; the scenario refuses it, and it is counted as
  "infeasible from the start" (not run) instead of among the refused layouts.

Prints the counts of missions and of violations per invariant; no timing is asserted anywhere.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from _results import json_option, write
from _results import table as results_table
from _sizes import size
from skymule.errors import SkymuleError
from skymule.experiments.layouts import random_autonomous_scenario
from skymule.metrics.flights import NO_SENSOR, MissionLog
from skymule.policies import make_policy
from skymule.scenario import Scenario, load_scenario, scenario_from_dict
from skymule.sim.run import run_mission
from skymule.world import Mission, build_mission

POLICIES = ("greedy", "hgad", "hgad-robust")


KINDS = ("outage", "gilbert-elliott", "snr-error", "missed-polls", "gps-error", "wind")


def random_fault(rng: np.random.Generator, kind: str) -> dict[str, object]:
    params: dict[str, object] = {
        "outage": {"mean_duration_s": float(rng.uniform(10, 120))},
        "gilbert-elliott": {"p_good_to_bad": float(rng.uniform(0.01, 0.1)), "p_bad_to_good": 0.2},
        "snr-error": {"std_db": float(rng.uniform(1, 9)), "correlation_s": 3.0},
        "missed-polls": {"probability": float(rng.uniform(0.0, 0.3))},
        "gps-error": {"std_m": float(rng.uniform(0.5, 8))},
        "wind": {"speed_mps": float(rng.uniform(1, 6)), "from_deg": float(rng.uniform(0, 360))},
    }[kind]
    return {"kind": kind, "params": params}


def random_mission(
    rng: np.random.Generator, fixed: Scenario, auto: Scenario
) -> tuple[dict[str, Any], Path]:
    """One random mission's scenario data (and the folder its paths are relative to)."""
    base = fixed if rng.random() < 0.5 else random_autonomous_scenario(rng, auto)
    data = base.to_toml_dict()
    for sensor in data["sensors"]:
        sensor["buffer_mbit"] = float(rng.uniform(50, 1500))
    data["seed"] = int(rng.integers(0, 2**31))
    data["policy"] = {"name": str(rng.choice(POLICIES))}
    kinds = rng.choice(KINDS, size=int(rng.integers(1, 4)), replace=False)  # one of each at most
    data["faults"] = [random_fault(rng, str(kind)) for kind in kinds]
    return data, Path(base.base_dir)


def home_unreachable(data: dict[str, Any]) -> bool:
    """True when the mission's wind is at least the UAV's speed: it could not fly back home."""
    trajectory = data["trajectory"]
    autonomous = trajectory.get("mode") == "autonomous"
    speed = trajectory.get("max_speed_mps" if autonomous else "speed_mps", 10.0)
    winds = [f["params"]["speed_mps"] for f in data["faults"] if f["kind"] == "wind"]
    return any(wind >= speed for wind in winds)


def violations(mission: Mission, log: MissionLog) -> dict[str, bool]:
    before = np.vstack([log.buffers_bit[None], log.remaining_bit[:-1]])
    taken = before - log.remaining_bit
    served = log.served != NO_SENSOR
    rows = np.flatnonzero(served)
    expected = np.minimum(
        log.rate_bps[rows, log.served[rows]] * log.slot_s, before[rows, log.served[rows]]
    )
    got = log.downloaded_bit[rows]
    found = {
        "downloads within buffers": bool(
            (log.remaining_bit < -1e-6).any() or (taken.sum(axis=0) > log.buffers_bit + 1e-6).any()
        ),
        "one sensor per slot": bool(((taken > 1e-9).sum(axis=1) > 1).any()),
        "only the served sensor": bool((taken[~served] > 1e-9).any()),
        "y = min(R dt, Q) or blocked": bool(
            ~np.all(np.isclose(got, expected, rtol=1e-9, atol=1e-6) | (got == 0))
        ),
    }
    if mission.mode == "autonomous":
        path = np.vstack([log.position_m, log.end_position_m[None]])[:, :2]
        fence = mission.fence
        inside = fence is None or bool(
            shapely.covers(fence.buffer(1e-5), shapely.points(path)).all()
        )
        steps = np.hypot(*np.diff(path, axis=0).T)
        found["inside the geofence"] = not inside
        found["speed cap"] = bool((steps > mission.max_step_m + 1e-6).any())
        if mission.return_home and log.home_m is not None:
            found["home at the end"] = bool(np.hypot(*(path[-1] - log.home_m)) > 1e-6)
    return found


def main() -> None:
    json_path = json_option()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--missions", type=int, default=size(10_000, 8))
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    fixed, auto = load_scenario("paper-sim-fixed"), load_scenario("paper-sim-autonomous")
    counts: dict[str, int] = {}
    windy_not_home = windy_runs = refused = infeasible = ran = 0
    start = time.process_time()
    for _ in range(args.missions):
        data, base_dir = random_mission(rng, fixed, auto)
        if home_unreachable(data):
            infeasible += 1  # the scenario refuses it in one line: not run
            continue
        try:
            scenario = scenario_from_dict(data, "random mission", base_dir)
            mission = build_mission(scenario)
        except SkymuleError:
            refused += 1  # e.g. a layout too short for the mission: one line, not run
            continue
        log = run_mission(mission, make_policy(scenario.policy))
        ran += 1
        windy = any(f.kind == "wind" for f in scenario.faults or [])
        found = violations(mission, log)
        for name, broken in found.items():
            counts[name] = counts.get(name, 0) + int(broken)
        if windy and "home at the end" in found:
            windy_runs += 1
            windy_not_home += found["home at the end"]
    seconds = time.process_time() - start
    print(f"{ran} missions with faults run ({refused} refused at build), {seconds:.1f} s CPU")
    for name, broken in sorted(counts.items()):
        print(f"  {name:32s} violated in {broken} missions")
    print(
        f"  {'home at the end, with wind':32s} missed in {windy_not_home} of {windy_runs} "
        "windy autonomous missions"
    )
    print(
        f"infeasible from the start (wind >= the UAV's speed: home unreachable, refused): "
        f"{infeasible}"
    )
    rows = [[name, str(broken)] for name, broken in sorted(counts.items())]
    rows.append(["home at the end, windy autonomous missions", f"{windy_not_home} of {windy_runs}"])
    note = (
        f"{ran} missions with faults run ({refused} refused at build, {infeasible} infeasible "
        f"from the start), {seconds:.1f} s CPU"
    )
    columns = ["invariant", "missions that violate it"]
    write(json_path, {"invariants": results_table(columns, rows, note=note, align="lr")})


if __name__ == "__main__":
    main()

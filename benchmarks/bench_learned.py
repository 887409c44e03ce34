"""The shipped ``learned`` policy against Greedy, HGAD, the planner and the upper bound.

Held-out random Lake Wheeler missions (seed 20250601, never trained or validated on): 300 s,
free space, buffers of 300-1500 Mbit per sensor that the UAV cannot empty, for 3, 4, 6 and 8
sensors, without faults and with faults (one random outage per tower, mean 60 s, and a 6 dB
SNR measurement error). Per condition and sensor count: mean download with a 95% confidence
interval (1.96 standard errors), the mean gap to the autonomous upper bound (fault-free: an
upper bound with faults too), and learned minus each other policy per mission (paired
difference, 95% CI), learned's mean and worst mission relative to HGAD and how many missions
it loses to HGAD by more than 5%. Then the decision regret on the recorded sample flights
(:func:`recorded_regret`), and the speed: one decision of one mission (inference, features
included) and the batched form inside the engine.

    python benchmarks/bench_learned.py                 # 200 missions per row (~20 min)
    python benchmarks/bench_learned.py --missions 50 --counts 4
    python benchmarks/bench_learned.py --sections recorded,speed
    python benchmarks/bench_learned.py --candidate W.npz --no-planner --sections held-out

``--candidate`` flies other weights next to the shipped ones on the same missions and prints
them against the shipped model and HGAD per mission (``candidate:`` lines).

**Decision regret on recorded traces.** ``skymule sim2real`` cannot score ``learned`` (nor the
planner): it replays the recorded flight sample by sample along its own path, and a policy
that steers leaves that path, to places where nothing was measured. Here the "real" world is
instead a radio map fitted (kriging, as ``skymule sim2real`` fits a flight ``--twin``) to the
recorded flight ``examples/samples/flight_merged.csv`` alone: SNR anywhere, equal to the
recording's smooth part on its lawnmower path (90 m between passes) and interpolated between
passes. Each policy flies ``paper-sim-autonomous`` (cut to the flight's 360 s) on the real map
and on each twin (the DT export ``dt_flight.csv`` and the second flight ``flight2_merged.csv``,
each fitted the same way, and the preset's free space); the twin's decisions (path and whom to
serve, slot by slot) are executed on the real map under the slot contract
(:func:`skymule.metrics.sim2real.execute`) and compared with the policy flown on the real map:
regret = (real policy - executed) / real policy, with the 90% block-bootstrap interval of
``skymule sim2real``. The replay is checked against the engine (the policy's own decisions
on the real map replay to its downloads exactly).

``--json PATH`` (``benchmarks/results/learned.json``) writes the table of docs/learning.md,
the speed as its note.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from _results import json_option, table, write
from _sizes import size
from learning.missions import HELD_OUT, HELD_OUT_FAULTS, draw_missions
from skymule.bounds.autonomous import autonomous_bound
from skymule.io.traces import positions_local, read_trace
from skymule.metrics.sim2real import DEFAULT_BOOTSTRAP, Estimate, execute, regret
from skymule.policies import HGAD, Greedy
from skymule.policies.learned import LearnedPolicy, load_net, shipped_weights
from skymule.policies.planner import Planner
from skymule.rules.contract import NO_SENSOR
from skymule.scenario import Scenario, load_scenario
from skymule.sim import compiled
from skymule.sim.run import run_mission, run_missions
from skymule.world import Mission, build_mission

HELD_OUT_SEED = 20250601
CONDITIONS = {"none": HELD_OUT, "faults": HELD_OUT_FAULTS}
SAMPLES = Path(__file__).resolve().parents[1] / "examples" / "samples"
REAL_FLIGHT = "flight_merged.csv"
TWINS = ("dt_flight.csv", "flight2_merged.csv", "paper-sim-autonomous")
RECORDED_POLICIES = ("greedy", "hgad", "planner", "learned")
OFF_PATH_M = 45.0
"""Half the recorded lawnmower's 90 m between passes: farther from every sample, the real map
extrapolates."""


def planner_and_bound(mission: Mission) -> tuple[float, float]:
    """(planner's download, upper bound) [bit] of one mission."""
    planner = float(run_mission(mission, Planner()).downloaded_bit.sum())
    return planner, float(autonomous_bound(mission).upper_bound_bit)


def mean_ci(values: np.ndarray) -> tuple[float, float]:
    """Mean and 95% half-width (1.96 standard errors)."""
    half = 1.96 * values.std(ddof=1) / np.sqrt(len(values)) if len(values) > 1 else 0.0
    return float(values.mean()), float(half)


def totals(
    missions: list[Mission], workers: int, candidate: str | None = None, planner: bool = True
) -> dict[str, np.ndarray]:
    """Bits downloaded per mission by every policy, and the bound (without ``planner``: no
    planner, no bound); ``candidate``: other weights flown as one more policy."""
    net = load_net(shipped_weights())
    out = {
        "learned": run_missions(missions, LearnedPolicy(net), detail=False).downloaded_bit,
        "greedy": run_missions(missions, Greedy(), detail=False).downloaded_bit,
        "hgad": run_missions(missions, HGAD(), detail=False).downloaded_bit,
    }
    if candidate is not None:
        policy = LearnedPolicy(load_net(candidate), "candidate")
        out["candidate"] = run_missions(missions, policy, detail=False).downloaded_bit
    got = {name: bits.sum(axis=1) for name, bits in out.items()}
    if planner:
        with ProcessPoolExecutor(workers) as pool:
            rows = np.array(list(pool.map(planner_and_bound, missions, chunksize=4)))
        got["planner"], got["bound"] = rows[:, 0], rows[:, 1]
    return got


def report(condition: str, n: int, got: dict[str, np.ndarray]) -> list[str]:
    """Print one block and its ``row:`` lines; return its row of the docs' table (n/a for the
    planner and the bound where they were not run)."""
    cells: dict[str, str] = {}
    bound = got.get("bound")
    learned = got["learned"]
    hgad = got["hgad"]
    label = "with" if condition == "faults" else "without"
    buffered = got["buffered"].mean() / 1e6
    print(f"\n{label} faults, {n} sensors, {len(learned)} missions ({buffered:.1f} Mbit buffered):")
    print("  policy     mean Mbit ± 95% CI   gap to bound   learned - policy [Mbit] ± 95% CI")
    names = ("learned", "candidate", "greedy", "hgad", "planner", "bound")
    for name in (name for name in names if name in got):
        mean, half = mean_ci(got[name] / 1e6)
        gap = float(np.mean((bound - got[name]) / bound)) if bound is not None else np.nan
        diff, diff_half = mean_ci((learned - got[name]) / 1e6)
        print(
            f"  {name:9s} {mean:8.1f} ± {half:5.1f}   {gap:6.1%}   {diff:+8.1f} ± {diff_half:5.1f}"
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
    if "candidate" in got:
        report_candidate(condition, n, got)
    return [
        "faults" if condition == "faults" else "none",
        str(n),
        str(len(learned)),
        *(cells.get(name, "n/a") for name in ("learned", "greedy", "hgad", "planner", "bound")),
        cells["diff hgad"],
        f"{100 * rel_mean:+.1f}% ± {100 * rel_half:.1f}",
        f"{100 * relative.min():+.1f}%, {below}",
        cells.get("diff planner", "n/a"),
        cells["gap learned"],
    ]


def report_candidate(condition: str, n: int, got: dict[str, np.ndarray]) -> None:
    """The candidate weights against the shipped model and HGAD, per mission."""
    candidate, learned, hgad = got["candidate"], got["learned"], got["hgad"]
    versus = (candidate - learned) / learned
    v_mean, v_half = mean_ci(versus)
    on_hgad = (candidate - hgad) / hgad
    h_mean, _ = mean_ci(on_hgad)
    below3 = int((on_hgad < -0.03).sum())
    print(
        f"  candidate vs learned: {v_mean:+.2%} ± {v_half:.2%} per mission, better in "
        f"{int((candidate > learned).sum())}, worse in {int((candidate < learned).sum())}; "
        f"vs hgad {h_mean:+.2%}, worst {on_hgad.min():+.2%}, more than 3% below in {below3}"
    )
    print(
        f"candidate: condition={condition} n={n} vs_learned={v_mean:.4f} "
        f"vs_learned_ci={v_half:.4f} vs_hgad={h_mean:.4f} worst_hgad={on_hgad.min():.4f} "
        f"below3={below3} missions={len(candidate)}"
    )


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


def on_map(base: Scenario, twin: str) -> Scenario:
    """``base`` under ``twin``: a recorded flight (.csv, fitted to a kriging map on the fly,
    as ``skymule sim2real`` fits one) or the preset itself (its model)."""
    if not twin.endswith(".csv"):
        return base
    signal = base.signal.model_copy(
        update={"source": "radiomap", "traces": [str(SAMPLES / twin)], "map": None, "trace": None}
    )
    return base.model_copy(update={"signal": signal})


def _flown(scenario: Scenario, policies: tuple[str, ...]) -> tuple[Mission, dict[str, Any]]:
    from skymule.tasks.compare import compare_policies

    mission = build_mission(scenario)
    runs = compare_policies(scenario, list(policies), bound=False, mission=mission).runs
    return mission, {run.policy: run.result.log for run in runs}


RegretTable = dict[str, dict[str, tuple[Estimate, float, float]]]


def recorded_regret(
    policies: tuple[str, ...] = RECORDED_POLICIES, twins: tuple[str, ...] = TWINS
) -> tuple[RegretTable, dict[str, float]]:
    """Per twin and policy on the recorded sample flight (module docstring): the decision
    regret, the Mbit its decisions on the twin download on the real map, and the Mbit the
    policy downloads flown on the real map; and per policy the share of its serving slots on
    the real map farther than :data:`OFF_PATH_M` from every recorded sample (where the real
    map is the kriging fit's extrapolation, not an interpolation between passes)."""
    base = load_scenario("paper-sim-autonomous")
    flight = read_trace(SAMPLES / REAL_FLIGHT)
    slot_s = base.mission.slot_s
    seconds = slot_s * round(float(flight.time_s[-1] - flight.time_s[0]) / slot_s + 1.0)
    base = base.model_copy(
        update={"mission": base.mission.model_copy(update={"duration_s": seconds})}
    )
    real, best = _flown(on_map(base, REAL_FLIGHT), policies)
    assert real.source is not None
    source = real.source
    recorded = positions_local(flight, real.frame.to_local)[:, :2]
    off_path = {}
    for name, log in best.items():
        serving = log.position_m[log.served != NO_SENSOR, :2]
        gap = np.hypot(*(serving[:, None, :] - recorded[None]).transpose(2, 0, 1)).min(axis=1)
        off_path[name] = float(np.mean(gap > OFF_PATH_M)) if gap.size else 0.0

    def replay(log: Any) -> np.ndarray:
        rates = np.asarray(real.rate_bps(source.snr_db(log.position_m)), float)
        return execute(rates, np.arange(log.n_slots), log.served, real.buffers_bit, real.slot_s)

    for name, log in best.items():  # the replay is the engine's, bit for bit
        if not np.allclose(replay(log), log.downloaded_bit, rtol=1e-12, atol=1e-3):
            raise SystemExit(f"recorded: {name}'s own decisions do not replay to its downloads")
    out: RegretTable = {}
    for twin in twins:
        _, flown = _flown(on_map(base, twin), policies)
        out[twin] = {}
        for name in policies:
            executed, own = replay(flown[name]), np.asarray(best[name].downloaded_bit, float)
            size_t = max(executed.size, own.size)
            estimate = regret(
                np.pad(executed, (0, size_t - executed.size)),
                np.pad(own, (0, size_t - own.size)),
                DEFAULT_BOOTSTRAP,
            )
            out[twin][name] = (estimate, executed.sum() / 1e6, own.sum() / 1e6)
    return out, off_path


def report_recorded(result: RegretTable, off_path: dict[str, float]) -> None:
    """Print the regret table and its ``recorded:`` lines, and learned against HGAD."""
    policies = list(next(iter(result.values())))
    print(
        f"\ndecision regret on the recorded flight {REAL_FLIGHT} (real = its kriging map; "
        "paper-sim-autonomous, 360 s), % with 90% CI, and Mbit executed on the real map:"
    )
    print("  twin                  " + "".join(f"{p:>30s}" for p in policies))
    for twin, row in result.items():
        cells = "".join(
            f"{100 * e.value:6.1f} [{100 * e.low:5.1f},{100 * e.high:5.1f}] {mbit:7.1f}"
            for e, mbit, _ in row.values()
        )
        print(f"  {twin:22s}{cells}")
        for name, (e, mbit, real_mbit) in row.items():
            print(
                f"recorded: twin={twin} policy={name} regret={e.value:.4f} low={e.low:.4f} "
                f"high={e.high:.4f} executed_mbit={mbit:.1f} real_mbit={real_mbit:.1f}"
            )
    means = {p: float(np.mean([row[p][0].value for row in result.values()])) for p in policies}
    executed = {p: float(np.mean([row[p][1] for row in result.values()])) for p in policies}
    own = {p: next(iter(result.values()))[p][2] for p in policies}
    print("  flown on the real map " + "".join(f"{own[p]:30.1f}" for p in policies))
    print(
        f"  serving slots more than {OFF_PATH_M:.0f} m from every recorded sample (there the "
        "real map extrapolates): " + ", ".join(f"{p} {off_path[p]:.0%}" for p in policies)
    )
    print("  mean over twins       " + "".join(
        f"{100 * means[p]:21.1f}% {executed[p]:7.1f}" for p in policies))  # fmt: skip
    if "learned" in means and "hgad" in means:
        worse = [t for t, row in result.items() if row["learned"][0].value > row["hgad"][0].value]
        verdict = "no worse than" if means["learned"] <= means["hgad"] else "worse than"
        print(
            f"  learned's mean regret {100 * means['learned']:.1f}% is {verdict} HGAD's "
            f"{100 * means['hgad']:.1f}%; above HGAD's on {len(worse)} of {len(result)} twins "
            f"({', '.join(worse) or 'none'})"
        )


def main() -> None:
    json_path: Path | None = json_option()
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--missions", type=int, default=size(200, 3))
    parser.add_argument("--counts", default=size("3,4,6,8", "3,4"))
    parser.add_argument("--conditions", default="none,faults")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--sections", default="held-out,recorded,speed", help="any of held-out, recorded, speed"
    )
    parser.add_argument("--candidate", help="other weights (.npz) to fly next to the shipped ones")
    parser.add_argument(
        "--no-planner", action="store_true", help="held-out: skip the planner and the bound"
    )
    args = parser.parse_args()
    sections = set(args.sections.split(","))
    counts = [int(c) for c in args.counts.split(",")]
    start = time.perf_counter()
    first: list[Mission] = []
    rows = []
    for condition in args.conditions.split(",") if "held-out" in sections else ():
        for n in counts:
            missions = draw_missions(HELD_OUT_SEED, n, args.missions, CONDITIONS[condition])
            first = first or missions
            got = totals(missions, args.workers, args.candidate, not args.no_planner)
            got["buffered"] = np.array([m.buffers_bit.sum() for m in missions])
            rows.append(report(condition, n, got))
    print(f"\n(evaluation {time.perf_counter() - start:.0f} s wall)")
    if "recorded" in sections:
        report_recorded(*recorded_regret())
    note = ""
    if "speed" in sections:
        first = first or draw_missions(HELD_OUT_SEED, counts[0], args.missions, HELD_OUT)
        note = speed(first, size(20, 2))
    if rows:  # the docs' table comes from the held-out section
        write(json_path, {"learned": table(COLUMNS, rows, note=note)})


if __name__ == "__main__":
    main()

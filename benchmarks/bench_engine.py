"""Fixed-path Greedy/HGAD on the engine: the compiled twin vs the numpy slot loop vs one mission
at a time.

Run: python benchmarks/bench_engine.py [n_missions] [n_single] [repeats] [--json PATH]
(~2 min; SKYMULE_BENCH_TINY=1: 4 missions of 40 slots, 1 single, 1 repeat, a 16 MB copy;
``--json benchmarks/results/engine.json``: the speed table's engine rows, docs/speed.md)

Missions: paper-sim-fixed (4 sensors, 500 slots) with random buffers. For each policy it prints
mission-slots per CPU-second (the machine is shared, so CPU time of this process is the fair
"per core" figure; each figure is the best of ``repeats``) of:

* single: ``run_mission`` one mission at a time (a batch of one, the numpy slot loop);
* numpy loop / compiled loop: ``run_missions`` on the whole batch, slot loop only (no
  per-slot detail);
* numpy + summaries / compiled + summaries: ``summarize_missions`` (what sweeps run: the
  ``metrics.summarize`` dictionaries, the compiled twin reducing each mission as it ends);

with the compiled/numpy ratio measured in the same run; then HGAD with summaries on missions
with faults (outages, Gilbert-Elliott loss, SNR error, missed polls), numpy vs compiled. Then
the bytes written per mission-slot (the loops' per-slot logs; the compiled summaries reduce
each mission as it ends and write none), this machine's memory bandwidth (best numpy copy of
a 256 MB array: read + write), and the rate memory would allow at the loops' bytes.
Without numba (``pip install skymule[fast]``) the compiled rows are skipped.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from _results import json_option, table, write
from _sizes import size
from skymule.policies import batch_policy
from skymule.scenario import PolicySpec, Scenario, load_scenario, scenario_from_dict
from skymule.sim import compiled
from skymule.sim.run import run_mission, run_missions, summarize_missions
from skymule.world import Mission, build_mission


def best_cpu_seconds(run: Callable[[], object], repeats: int) -> float:
    """Least CPU time of this process over ``repeats`` calls of ``run`` [s]."""
    times = []
    for _ in range(repeats):
        start = time.process_time()
        run()
        times.append(time.process_time() - start)
    return max(min(times), 1e-9)


def memory_bandwidth_bps(repeats: int = 5, size_bytes: int = 256 * 2**20) -> float:
    """Bytes per second a numpy copy moves (read + write), best of ``repeats``."""
    source = np.ones(size_bytes // 8)
    target = np.empty_like(source)
    seconds = best_cpu_seconds(lambda: np.copyto(target, source), repeats)
    return 2 * size_bytes / seconds


def bench_policy(
    name: str, missions: list[Mission], n_single: int, repeats: int
) -> dict[str, float]:
    """Print each path's mission-slots per CPU-second and return them by path."""
    specs = [PolicySpec(name=name)] * len(missions)
    names = [m.scenario.name for m in missions]

    def loop(engine: str) -> object:
        return run_missions(missions, batch_policy(specs), detail=False, engine=engine)

    slots = int(run_missions(missions, batch_policy(specs), engine="numpy").n_run.sum())
    single = missions[:n_single]
    single_slots = sum(m.n_slots for m in single)
    rate = single_slots / best_cpu_seconds(
        lambda: [run_mission(m, batch_policy(specs[:1]), "numpy") for m in single], repeats
    )
    print(f"{name:6s} {'single (' + str(n_single) + ' missions)':28s} {rate / 1e6:8.2f} M")
    engines = ["numpy", "compiled"] if compiled.available() else ["numpy"]
    rates: dict[str, float] = {"single": rate}
    for engine in engines:
        paths: dict[str, Callable[[], object]] = {
            "loop": lambda e=engine: loop(e),
            "+ summaries": lambda e=engine: summarize_missions(
                missions, specs, names, batch_size=len(missions), engine=e
            ),
        }
        paths["loop"]()  # compile (or load the compiled loop from disk) outside the timing
        for label, run in paths.items():
            rates[f"{engine} {label}"] = slots / best_cpu_seconds(run, repeats)
            ratio = ""
            if engine == "compiled":
                ratio = f"x{rates[f'{engine} {label}'] / rates[f'numpy {label}']:.1f} vs numpy"
            print(f"{name:6s} {engine + ' ' + label:28s} {rates[f'{engine} {label}'] / 1e6:8.2f} M"
                  f"  {ratio}")  # fmt: skip
    return rates


def bench_faults(base: Mission, n_missions: int, repeats: int) -> None:
    """HGAD on missions with outages, Gilbert-Elliott loss, an SNR error and missed polls:
    numpy vs compiled (which applies the same fault draws), with summaries."""
    faulty = [build_mission(with_faults(base.scenario, seed)) for seed in range(5)]
    rng = np.random.default_rng(1)
    missions = [
        replace(faulty[i % len(faulty)], buffers_bit=rng.uniform(200e6, 1500e6, base.n_sensors))
        for i in range(n_missions)
    ]
    specs = [PolicySpec(name="hgad")] * n_missions
    names = [m.scenario.name for m in missions]
    slots = int(run_missions(missions, batch_policy(specs), detail=False).n_run.sum())
    rates = {}
    for engine in ["numpy", "compiled"] if compiled.available() else ["numpy"]:
        run = lambda e=engine: summarize_missions(  # noqa: E731
            missions, specs, names, batch_size=n_missions, engine=e
        )
        run()
        rates[engine] = slots / best_cpu_seconds(run, repeats)
        ratio = f"x{rates[engine] / rates['numpy']:.1f} vs numpy" if engine == "compiled" else ""
        label = f"faults, {engine} + summaries"
        print(f"{'hgad':6s} {label:28s} {rates[engine] / 1e6:8.2f} M  {ratio}")


def with_faults(scenario: Scenario, seed: int) -> Scenario:
    """``scenario`` with every per-slot fault kind a fixed batch applies (``docs/faults.md``)."""
    data = scenario.to_toml_dict()
    data["seed"] = seed
    data["faults"] = [
        {"kind": "outage", "params": {"mean_duration_s": 60.0}},
        {"kind": "gilbert-elliott", "params": {"p_good_to_bad": 0.05, "p_bad_to_good": 0.3}},
        {"kind": "snr-error", "params": {"std_db": 4.0, "correlation_s": 3.0}},
        {"kind": "missed-polls", "params": {"probability": 0.05}},
    ]
    return scenario_from_dict(data, scenario.name, Path(scenario.base_dir))


def main(
    n_missions: int = 2000, n_single: int = 50, repeats: int = 3, json_path: Path | None = None
) -> None:
    base = build_mission(load_scenario("paper-sim-fixed", size([], ["mission.duration_s=40"])))
    rng = np.random.default_rng(0)
    missions = [
        replace(base, buffers_bit=rng.uniform(200e6, 1500e6, base.n_sensors))
        for _ in range(n_missions)
    ]
    print(
        f"{n_missions} missions x {base.n_slots} slots x {base.n_sensors} sensors; "
        f"mission-slots per CPU-second, best of {repeats}"
        + ("" if compiled.available() else " (numba not installed: numpy only)")
    )
    rates = {name: bench_policy(name, missions, n_single, repeats) for name in ("greedy", "hgad")}
    bench_faults(base, n_missions, repeats)
    # per mission-slot each loop writes served (int64), downloaded (float64), hovering (bool)
    # and the track sample (int64) (no (B, T, N) buffer log: summaries do not need it); the
    # compiled loop with summaries writes no per-slot log at all, only each mission's
    # reductions (8 numbers and N first-visit slots) and ends (slots run, end, N buffers)
    written = 8 + 8 + 1 + 8
    per_mission = 8 * (8 + base.n_sensors) + 8 * (2 + base.n_sensors)
    bandwidth = memory_bandwidth_bps(size(5, 1), size(256, 16) * 2**20)
    print(
        f"bytes written per mission-slot: {written} by either loop ({written + 8 * base.n_sensors} "
        f"with the buffer log); compiled + summaries {per_mission / base.n_slots:.2f} "
        f"({per_mission} B per mission, no per-slot log)"
    )
    print(f"memory bandwidth (numpy copy, read + write): {bandwidth / 1e9:.1f} GB/s")
    print(f"memory-bound ceiling at {written} B: {bandwidth / written / 1e6:.0f} M mission-slots/s")
    write(json_path, {"speed-engine": speed_rows(rates, n_missions, written, bandwidth)})


def speed_rows(
    rates: dict[str, dict[str, float]], n_missions: int, written: int, bandwidth: float
) -> dict[str, object]:
    """The speed table's engine rows (docs/speed.md) from the measured rates [slots/CPU-s]."""
    g, h = rates["greedy"], rates["hgad"]
    rows = [
        [
            "one mission at a time (`run_mission`, a batch of one), paper-sim-fixed",
            f"{g['single'] / 1e6:.2f} M (Greedy) / {h['single'] / 1e6:.2f} M (HGAD) "
            "mission-slots per CPU-s",
            "`python benchmarks/bench_engine.py`",
        ],
        [
            f"engine, numpy slot loop, {n_missions:,} × paper-sim-fixed",
            f"Greedy {g['numpy + summaries'] / 1e6:.1f} M mission-slots/CPU-s with summaries "
            f"({g['numpy loop'] / 1e6:.1f} M slot loop only), HGAD "
            f"{h['numpy + summaries'] / 1e6:.1f} M ({h['numpy loop'] / 1e6:.1f} M)",
            "same",
        ],
    ]
    if "compiled loop" in g:
        parts = [
            f"{label} {r['compiled + summaries'] / 1e6:.1f} M with summaries "
            f"(**×{r['compiled + summaries'] / r['numpy + summaries']:.1f}** numpy), "
            f"{r['compiled loop'] / 1e6:.1f} M loop"
            for label, r in (("Greedy", g), ("HGAD", h))
        ]
        rows.append(
            [
                "engine, compiled twin (`fast` extra, numba)",
                f"{'; '.join(parts)}; {written} bytes written per mission-slot against "
                f"{bandwidth / 1e9:.1f} GB/s measured memory bandwidth",
                "same",
            ]
        )
    return table(["what", "figure", "command"], rows, align="lll")


if __name__ == "__main__":
    json_path = json_option()
    defaults = size((1000, 100, 3), (4, 1, 1))
    given = [int(a) for a in sys.argv[1:]]
    n_missions, n_single, repeats = [*given, *defaults[len(given) :]][:3]
    main(n_missions, n_single, repeats, json_path=json_path)

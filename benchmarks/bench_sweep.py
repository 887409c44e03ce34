"""Sweep overhead: cost per mission at 10k and 100k missions, executors, the seed axis, memory.

Run: ``python benchmarks/bench_sweep.py [--old-rev REV] [--old-large] [--quick]``

Cases (paper-sim-fixed, Greedy and HGAD paired, random buffers), each in its own process
so peak memory (main + workers, sampled every 0.2 s) and imports are its own:

* ``sample-10k`` / ``sample-100k``: ``mode = {sample = N}`` x 2 policies, in-process;
* ``process-10k`` / ``process-100k``: the same on the ``process`` executor with 2 workers
  (at 10k the workers' start-up, ~1 s of imports each, is a large share);
* ``seeds-10k``: ``policy x seed = {range = [0, 5000]}``, in-process: 10,000 missions over
  5,000 seeds (the same work as ``sample-10k`` with a seed axis instead of sampling).

Figures are CPU seconds (this process and its workers): the machine may be shared. Targets
printed at the end: cost per mission of 100k within 1.2x of 10k; ``process`` on
2 workers >= 1.7x in-process (wall time: needs two idle cores); the seed axis within 1.3x of
the same sweep without it; peak memory flat from 10k to 100k.

``--old-rev REV`` runs the same cases on another commit (``git archive REV`` into a temporary
folder, e.g. ``--old-rev main``) in the same run and prints the ratio; its 100k case (several
minutes) only with ``--old-large``. ``--quick`` skips the 100k case.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
from pathlib import Path

from _sizes import size

SAMPLE = """
base = "paper-sim-fixed"
seed = 1
mode = {{ sample = {n} }}
[axes]
policy.name = ["greedy", "hgad"]
"sensors[*].buffer_mbit" = {{ dist = "uniform", low = 200, high = 1500 }}
"""

SEEDS = """
base = "paper-sim-fixed"
seed = 1
[axes]
policy.name = ["greedy", "hgad"]
seed = {{ range = [0, {n}] }}
"sensors[*].buffer_mbit" = {{ dist = "uniform", low = 200, high = 1500 }}
"""

SMALL, LARGE = size(5_000, 5), size(50_000, 10)

CASES: dict[str, tuple[str, int, str, int | None]] = {
    "sample-10k": (SAMPLE, SMALL, "inprocess", None),
    "sample-100k": (SAMPLE, LARGE, "inprocess", None),
    "process-10k": (SAMPLE, SMALL, "process", 2),
    "process-100k": (SAMPLE, LARGE, "process", 2),
    "seeds-10k": (SEEDS, SMALL, "inprocess", None),
}
"""name -> (sweep template, N, executor, workers); SKYMULE_BENCH_TINY=1: a few missions."""


def _rss_bytes() -> int:
    import psutil

    me = psutil.Process()
    total = me.memory_info().rss
    for child in me.children(recursive=True):
        with contextlib.suppress(psutil.Error):
            total += child.memory_info().rss
    return total


def measure(case: str) -> dict[str, float]:
    """Run one case in this process; wall and CPU seconds, missions and peak RSS."""
    from skymule.experiments.run import run_sweep
    from skymule.experiments.sweep import parse_sweep

    template, n, executor, workers = CASES[case]
    spec = parse_sweep(tomllib.loads(template.format(n=n)), "bench", Path("."))
    peak = [0]
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            peak[0] = max(peak[0], _rss_bytes())
            time.sleep(0.2)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    with tempfile.TemporaryDirectory() as folder:
        wall, cpu, main = time.perf_counter(), _cpu_s(), time.process_time()
        outcome = run_sweep(
            spec, Path(folder) / "out", executor=executor, workers=workers, progress=False
        )
        wall, cpu = time.perf_counter() - wall, _cpu_s() - cpu
        main = time.process_time() - main
    stop.set()
    sampler.join()
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "main_cpu_s": main,
        "missions": outcome.n_missions,
        "peak_b": peak[0],
    }


def _cpu_s() -> float:
    """CPU seconds of this process and its finished children (the process pool's workers)."""
    me, children = (
        resource.getrusage(resource.RUSAGE_SELF),
        resource.getrusage(resource.RUSAGE_CHILDREN),
    )
    return me.ru_utime + me.ru_stime + children.ru_utime + children.ru_stime


def run_case(case: str, src: Path) -> dict[str, float]:
    """``measure(case)`` in a fresh interpreter importing skymule from ``src``."""
    env = {**os.environ, "PYTHONPATH": str(src)}
    command = [sys.executable, __file__, "--one", case]
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{case} ({src}) failed:\n{done.stderr}")
    result: dict[str, float] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def _line(case: str, new: dict[str, float], old: dict[str, float] | None) -> str:
    per = 1e6 * new["cpu_s"] / new["missions"]
    text = (
        f"{case:<12} {int(new['missions']):>7} missions: {new['cpu_s']:6.1f} s CPU "
        f"({new['main_cpu_s']:5.1f} s in main, {new['wall_s']:6.1f} s wall), "
        f"{per:5.0f} us CPU/mission, "
        f"peak {new['peak_b'] / 2**20:4.0f} MiB"
    )
    if old is not None:
        text += (
            f" | previous {old['cpu_s']:6.1f} s CPU ({old['wall_s']:.1f} s wall), "
            f"{old['peak_b'] / 2**20:4.0f} MiB -> {old['cpu_s'] / new['cpu_s']:.1f}x less CPU"
        )
    return text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--one", choices=sorted(CASES), help=argparse.SUPPRESS)
    parser.add_argument("--old-rev", help="also run the cases on this git revision")
    parser.add_argument("--old-large", action="store_true", help="previous code at 100k too")
    parser.add_argument("--quick", action="store_true", help="skip the 100k case")
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(args.one)))
        return
    repo = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory() as old_tree:
        if args.old_rev:
            archive = subprocess.run(
                ["git", "-C", str(repo), "archive", args.old_rev],
                capture_output=True,
                check=True,
            ).stdout
            subprocess.run(["tar", "-x", "-C", old_tree], input=archive, check=True)
        results: dict[str, dict[str, float]] = {}
        for case in CASES:
            large = case.endswith("100k")
            if (args.quick or size(False, True)) and large:
                continue
            results[case] = run_case(case, repo / "src")
            old = None
            if args.old_rev and (not large or args.old_large):
                old = run_case(case, Path(old_tree) / "src")
            print(_line(case, results[case], old), flush=True)
    small, seeds = results["sample-10k"], results["seeds-10k"]
    for scale in ("10k", "100k"):
        if f"process-{scale}" not in results:
            continue
        alone, proc = results[f"sample-{scale}"], results[f"process-{scale}"]
        # on two idle cores the wall time is at least the serial main part and half the rest
        ideal = alone["cpu_s"] / max(proc["main_cpu_s"], proc["cpu_s"] / 2)
        print(
            f"process executor, 2 workers, {scale}: {alone['wall_s'] / proc['wall_s']:.2f}x "
            f"in-process in wall time (target >= 1.7; load {os.getloadavg()[0]:.1f} on "
            f"{os.cpu_count()} cores), {ideal:.2f}x on two idle cores from the CPU split "
            f"(main {proc['main_cpu_s']:.1f} s, all {proc['cpu_s']:.1f} s)"
        )
    seed_cost = seeds["cpu_s"] / small["cpu_s"]
    print(f"seed axis: {seed_cost:.2f}x the CPU of the same sweep without it (target <= 1.3)")
    if "sample-100k" in results:
        large = results["sample-100k"]
        per_mission = (large["cpu_s"] / large["missions"]) / (small["cpu_s"] / small["missions"])
        print(f"CPU per mission, 100k / 10k: {per_mission:.2f}x (target <= 1.2)")
        print(
            f"peak memory: {small['peak_b'] / 2**20:.0f} MiB at 10k, "
            f"{large['peak_b'] / 2**20:.0f} MiB at 100k"
        )


if __name__ == "__main__":
    main()

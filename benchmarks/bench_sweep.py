"""Sweep wall time and peak memory.

Run: python benchmarks/bench_sweep.py [n_layouts] [executor] [chunk_size]
(SKYMULE_BENCH_TINY=1: 5 layouts, in process, chunks of 4)
Sweeps paper-sim-fixed x {greedy, hgad} over n_layouts random buffer draws (2 x n_layouts
missions) into a temporary folder; prints wall time and peak RSS of this process plus its
workers (sampled every 0.2 s).
"""

from __future__ import annotations

import contextlib
import sys
import tempfile
import threading
import time
from pathlib import Path

import psutil
from _sizes import size

from skymule.experiments.run import run_sweep
from skymule.experiments.sweep import parse_sweep

SWEEP = """
base = "paper-sim-fixed"
seed = 1
mode = {{ sample = {n} }}
[axes]
policy.name = ["greedy", "hgad"]
"sensors[*].buffer_mbit" = {{ dist = "uniform", low = 200, high = 1500 }}
"""


def _rss_bytes(process: psutil.Process) -> int:
    total = process.memory_info().rss
    for child in process.children(recursive=True):
        with contextlib.suppress(psutil.Error):
            total += child.memory_info().rss
    return total


def main(n_layouts: int = 5000, executor: str = "process", chunk_size: int = 500) -> None:
    import tomllib

    spec = parse_sweep(tomllib.loads(SWEEP.format(n=n_layouts)), "bench", Path("."))
    me = psutil.Process()
    peak = [0]
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            peak[0] = max(peak[0], _rss_bytes(me))
            time.sleep(0.2)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        outcome = run_sweep(
            spec, Path(folder), executor=executor, chunk_size=chunk_size, progress=False
        )
        seconds = time.perf_counter() - start
    stop.set()
    sampler.join()
    print(
        f"{outcome.n_missions} missions ({executor}, chunk {chunk_size}): {seconds:.1f} s, "
        f"{outcome.n_missions / seconds:,.0f} missions/s, peak RSS {peak[0] / 2**20:,.0f} MiB "
        "(main + workers)"
    )
    print(outcome.summary.to_string(index=False))


if __name__ == "__main__":
    n_layouts, executor, chunk_size = size((5000, "process", 500), (5, "inprocess", 4))
    args = sys.argv[1:]
    main(
        int(args[0]) if args else n_layouts,
        args[1] if len(args) > 1 else executor,
        int(args[2]) if len(args) > 2 else chunk_size,
    )

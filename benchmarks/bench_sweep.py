"""Sweep overhead: cost per mission at 10k and 100k missions, executors, the seed axis, memory.

Run: ``python benchmarks/bench_sweep.py [--old-rev REV] [--old-large] [--quick] [--paths]``, or
at scale:
``python benchmarks/bench_sweep.py --missions N[,N...] [--executors E[,E...]] [--report]``

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

``--missions N`` (scale mode) runs the same sweep (``mode = {sample = N/2}`` x 2 policies)
of N missions on each of ``--executors`` (default ``inprocess,process,dask-local``, 2 workers)
and prints, per size and executor, wall and CPU seconds (this process and every worker), CPU
per mission and peak RSS (all processes, sampled every 0.2 s). ``--report`` then times
``skymule report`` on the largest sweep (its wall time and peak RSS, in a fresh process);
``--keep DIR`` keeps the sweep folders in DIR; ``--report-only DIR`` times the report of an
existing sweep folder. Targets printed at the end: peak RSS flat with N (200,000 within
60 MiB of 20,000), ``dask-local`` CPU within 1.15x of ``inprocess``, CPU per mission at
10,000,000 within 1.1x of 100,000, the report in under a minute.

The paths to the engine (issue 33), each in a fresh process, printed next to the issue's
figure and target (and, with ``--old-rev``, the other commit's figure in the same run); also
alone with ``--paths``:

* a fixed sweep of 20,000 missions of paper-sim-fixed with the buffers drawn per mission:
  ``run_sweep`` in-process and ``skymule sweep --executor inprocess`` (CPU per mission), and
  the engine with summaries alone on the same missions (the floor);
* a batched plug-in without ``Params`` and the same with ``Params``, swept over 4,000
  missions with drawn buffers, and ``simulate()`` of its per-mission form (CPU per mission);
* ``simulate()`` of one paper-sim-fixed mission in a warm process (median CPU of 30 calls
  after 30);
* re-running a finished sweep on ``dask-local`` (wall seconds: nothing to run).

``--old-rev REV`` runs the same cases on another commit (``git archive REV`` into a temporary
folder, e.g. ``--old-rev main``) in the same run and prints the ratio; its 100k case (several
minutes) only with ``--old-large``. ``--quick`` skips the 100k case.

``--json PATH`` writes the speed table's sweep rows (``speed-sweep``,
``benchmarks/results/sweep.json``) or, in scale mode, the rows of the sweep-scale table
(``benchmarks/results/sweep-scale.json``: rows of other sizes and executors already in the file
are kept, so runs of different sizes fill one table; docs/speed.md, docs/sweeps.md).
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
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from _results import json_option, table, write
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


class PeakRss:
    """Peak RSS of this process and its children, sampled every 0.2 s while in the block;
    ``cpu_s``: the CPU seconds the sampling took (walking /proc for the children)."""

    def __enter__(self) -> PeakRss:
        self.peak = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def _sample(self) -> None:
        while not self._stop.is_set():
            self.peak = max(self.peak, _rss_bytes())
            time.sleep(0.2)
        self.cpu_s = time.thread_time()  # the sampling's own CPU (not the sweep's)

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)


def measure_sweep(text: str, executor: str, workers: int | None, out: Path) -> dict[str, float]:
    """Run one sweep in this process; wall and CPU seconds, missions and peak RSS."""
    from skymule.experiments.run import run_sweep
    from skymule.experiments.sweep import parse_sweep

    spec = parse_sweep(tomllib.loads(text), "bench", Path("."))
    with PeakRss() as rss:
        wall, cpu, main = time.perf_counter(), _cpu_s(), time.process_time()
        outcome = run_sweep(spec, out, executor=executor, workers=workers, progress=False)
        wall, cpu = time.perf_counter() - wall, _cpu_s() - cpu
        main = time.process_time() - main
    return {
        "wall_s": wall,
        "cpu_s": cpu - rss.cpu_s,
        "main_cpu_s": main - rss.cpu_s,
        "missions": outcome.n_missions,
        "peak_b": rss.peak,
    }


def measure(case: str) -> dict[str, float]:
    """Run one case in this process (in a temporary folder)."""
    template, n, executor, workers = CASES[case]
    with tempfile.TemporaryDirectory() as folder:
        return measure_sweep(template.format(n=n), executor, workers, Path(folder) / "out")


def measure_report(folder: Path) -> dict[str, float]:
    """``skymule report FOLDER`` (with PDFs) in this process: wall seconds and peak RSS."""
    from skymule.report.build import build_report

    with PeakRss() as rss:
        wall, cpu = time.perf_counter(), time.process_time()
        build_report(folder)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return {"wall_s": wall, "cpu_s": cpu - rss.cpu_s, "peak_b": rss.peak}


def _cpu_s() -> float:
    """CPU seconds of this process and its finished children (the process pool's workers)."""
    me, children = (
        resource.getrusage(resource.RUSAGE_SELF),
        resource.getrusage(resource.RUSAGE_CHILDREN),
    )
    return me.ru_utime + me.ru_stime + children.ru_utime + children.ru_stime


def _missions_in(folder: Path) -> int:
    import pyarrow.parquet as pq

    return int(pq.read_metadata(folder / "results.parquet").num_rows)


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


# --- the paths to the engine (issue 33) ---------------------------------------------------


class ServeFirstBatched:
    """A user's batched policy without ``Params``: serve sensor 0 while it has data."""

    name = "serve-first"
    batched = True

    def reset(self, contexts: Sequence[Any]) -> None:
        pass

    def act(self, observation: Any) -> Any:
        from skymule.policies.base import BatchAction

        return BatchAction(serve=np.where(observation.remaining_bit[:, 0] > 0, 0, -1))


class ServeFirstParams(BaseModel):
    """No parameter to set: the model's presence is what differs."""


class ServeFirstBatchedParams(ServeFirstBatched):
    """:class:`ServeFirstBatched` with a ``Params`` model."""

    Params = ServeFirstParams

    def __init__(self, params: ServeFirstParams) -> None:
        self.params = params


class ServeFirst:
    """The per-mission form of :class:`ServeFirstBatched`."""

    name = "serve-first"

    def reset(self, context: Any) -> None:
        pass

    def act(self, observation: Any) -> Any:
        from skymule.policies.base import Action

        return Action(serve=0 if observation.remaining_bit[0] > 0 else None)


FIXED_SWEEP = """
base = "paper-sim-fixed"
seed = 1
mode = {{ sample = {n} }}
[axes]
{policy}"sensors[*].buffer_mbit" = {{ dist = "uniform", low = 200, high = 1500 }}
"""

PATH_MISSIONS, PLUGIN_MISSIONS = size(20_000, 40), size(4_000, 20)
PER_MISSION_RUNS, SIMULATE_CALLS = size(20, 2), size(30, 3)


@dataclass(frozen=True)
class PathRow:
    """One row of the issue's table: what it measures, its unit, the issue's figure, the
    target (None: relative, see :func:`_path_verdicts`)."""

    label: str
    unit: str
    issue: float
    target: float | None


PATHS: dict[str, PathRow] = {
    "sweep-api": PathRow("fixed sweep, run_sweep (API)", "us/mission", 305, 60),
    "sweep-cli": PathRow("fixed sweep, skymule sweep (CLI)", "us/mission", 389, 80),
    "sweep-engine": PathRow("  engine + summaries alone, same missions", "us/mission", 26, None),
    "plugin-no-params": PathRow("batched plug-in without Params, sweep", "us/mission", 8523, None),
    "plugin-params": PathRow("batched plug-in with Params, sweep", "us/mission", 413, None),
    "plugin-per-mission": PathRow("its per-mission form, simulate()", "us/mission", 12479, None),
    "simulate": PathRow("simulate(), one paper-sim-fixed mission, warm", "ms", 17.9, 2.0),
    "dask-rerun": PathRow("re-run of a finished sweep, dask-local", "s wall", 13.0, None),
}
"""name -> row; measured by :func:`measure_path` in a fresh process each."""


def _sweep_spec(n: int, policy: str = "") -> Any:
    from skymule.experiments.sweep import parse_sweep

    line = f'policy.name = ["{policy}"]\n' if policy else ""
    return parse_sweep(tomllib.loads(FIXED_SWEEP.format(n=n, policy=line)), "bench", Path("."))


def _sweep_cpu_us(n: int, policy: str = "") -> float:
    """CPU per mission of ``run_sweep`` in-process (after a 50-mission sweep loads the
    compiled engine)."""
    from skymule.experiments.run import run_sweep

    with tempfile.TemporaryDirectory() as folder:
        run_sweep(_sweep_spec(50, policy), Path(folder) / "warm", executor="inprocess",
                  progress=False)  # fmt: skip
        start = time.process_time()
        run_sweep(_sweep_spec(n, policy), Path(folder) / "out", executor="inprocess",
                  progress=False)  # fmt: skip
        return 1e6 * (time.process_time() - start) / n


def _engine_cpu_us(n: int) -> float:
    """CPU per mission of the engine with summaries on the sweep's missions, built outside
    the timing (with calls both revisions have)."""
    from dataclasses import replace

    from skymule.experiments.sweep import sweep_plan
    from skymule.sim.run import summarize_missions
    from skymule.world import build_mission

    plan = sweep_plan(_sweep_spec(n))
    scenarios = [plan.resolve.validate(m) for m in plan.missions()]
    built = replace(build_mission(scenarios[0]), source=None)
    missions = [
        replace(built, scenario=s, buffers_bit=np.array([x.buffer_mbit for x in s.sensors]) * 1e6)
        for s in scenarios
    ]
    policies, names = [s.policy for s in scenarios], [s.name for s in scenarios]
    summarize_missions(missions[:50], policies[:50], names[:50])  # the compiled engine loaded
    start = time.process_time()
    summarize_missions(missions, policies, names)
    return 1e6 * (time.process_time() - start) / n


def _cli_cpu_us(n: int, src: Path) -> float:
    """CPU per mission of ``skymule sweep --executor inprocess`` (its start-up included)."""
    with tempfile.TemporaryDirectory() as folder:
        sweep = Path(folder) / "sweep.toml"
        sweep.write_text(FIXED_SWEEP.format(n=n, policy=""))
        env = {**os.environ, "PYTHONPATH": str(src)}
        command = [sys.executable, "-m", "skymule", "sweep", str(sweep), "--executor",
                   "inprocess", "--quiet", "--out"]  # fmt: skip
        subprocess.run([*command, f"{folder}/warm"], env=env, capture_output=True, check=False)
        before = _children_cpu_s()
        done = subprocess.run([*command, f"{folder}/out"], env=env, capture_output=True,
                              text=True, check=False)  # fmt: skip
        if done.returncode != 0:
            raise SystemExit(f"skymule sweep failed:\n{done.stderr}")
        return 1e6 * (_children_cpu_s() - before) / n


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _per_mission_cpu_us(runs: int) -> float:
    """CPU per mission of ``simulate()`` under the per-mission plug-in (buffers varied)."""
    from skymule.scenario import load_scenario
    from skymule.tasks.simulate import simulate

    base = load_scenario("paper-sim-fixed").with_policy("bench_sweep:ServeFirst")
    simulate(base)
    rng = np.random.default_rng(1)
    scenarios = []
    for _ in range(runs):
        sensors = [
            s.model_copy(update={"buffer_mbit": float(rng.uniform(200, 1500))})
            for s in base.sensors
        ]
        scenarios.append(base.model_copy(update={"sensors": sensors}))
    start = time.process_time()
    for scenario in scenarios:
        simulate(scenario)
    return 1e6 * (time.process_time() - start) / runs


def _simulate_ms(calls: int) -> float:
    """Median CPU of ``simulate()`` of paper-sim-fixed over ``calls`` calls after ``calls``."""
    from skymule.scenario import load_scenario
    from skymule.tasks.simulate import simulate

    scenario = load_scenario("paper-sim-fixed")
    for _ in range(calls):  # a warm process: past the compiled engine's break-even
        simulate(scenario)
    times = []
    for _ in range(calls):
        start = time.process_time()
        simulate(scenario)
        times.append(time.process_time() - start)
    return 1e3 * float(np.median(times))


def _dask_rerun_s(n: int) -> float:
    """Wall seconds of re-running a finished sweep on ``dask-local`` (2 workers)."""
    import importlib.util

    if importlib.util.find_spec("distributed") is None:
        return float("inf")  # (the `dask` extra is not installed)
    from skymule.experiments.run import run_sweep

    with tempfile.TemporaryDirectory() as folder:
        spec = _sweep_spec(n)
        run_sweep(spec, Path(folder) / "out", executor="inprocess", progress=False)
        start = time.perf_counter()
        run_sweep(spec, Path(folder) / "out", executor="dask-local", workers=2, progress=False)
        return time.perf_counter() - start


def measure_path(name: str, src: Path) -> float:
    """The figure of one :data:`PATHS` row, in this process (``src``: the CLI's code)."""
    if name == "sweep-api":
        return _sweep_cpu_us(PATH_MISSIONS)
    if name == "sweep-cli":
        return _cli_cpu_us(PATH_MISSIONS, src)
    if name == "sweep-engine":
        return _engine_cpu_us(PATH_MISSIONS)
    if name == "plugin-no-params":
        return _sweep_cpu_us(PLUGIN_MISSIONS, "bench_sweep:ServeFirstBatched")
    if name == "plugin-params":
        return _sweep_cpu_us(PLUGIN_MISSIONS, "bench_sweep:ServeFirstBatchedParams")
    if name == "plugin-per-mission":
        return _per_mission_cpu_us(PER_MISSION_RUNS)
    if name == "simulate":
        return _simulate_ms(SIMULATE_CALLS)
    if name == "dask-rerun":
        return _dask_rerun_s(size(100, 10))
    raise ValueError(name)


def run_paths(src: Path, old_src: Path | None) -> None:
    """Every :data:`PATHS` row in a fresh process each (and on the old tree), printed next to
    the issue's figure and target; then the relative targets."""
    found: dict[str, float] = {}
    for name, row in PATHS.items():
        value = _subprocess_json("--one-path", name, src=src)["value"]
        found[name] = value
        target = "" if row.target is None else f", target <= {row.target:g}"
        text = f"path {row.label:<46} {value:9.1f} {row.unit:<10} (issue 33: {row.issue:g}{target})"
        if old_src is not None:
            old = _subprocess_json("--one-path", name, src=old_src)["value"]
            text += f" | previous {old:9.1f} -> {old / max(value, 1e-9):.1f}x less"
        print(text, flush=True)
    for line in _path_verdicts(found):
        print(line, flush=True)


def _path_verdicts(found: dict[str, float]) -> list[str]:
    """The targets of the issue's table, met or missed."""
    lines = []
    for name, row in PATHS.items():
        if row.target is not None and name in found:
            met = "met" if found[name] <= row.target else "MISSED"
            lines.append(
                f"target {row.label}: {found[name]:.1f} {row.unit} <= {row.target:g}: {met}"
            )
    if {"plugin-no-params", "plugin-params"} <= set(found):
        ratio = found["plugin-no-params"] / found["plugin-params"]
        lines.append(
            f"target plug-in without Params / with Params: {ratio:.2f}x (target: about 1; "
            f"issue 33: 20.6x)"
        )
    if {"plugin-no-params", "plugin-per-mission"} <= set(found):
        gain = found["plugin-per-mission"] / found["plugin-no-params"]
        met = "met" if gain >= 100 else "MISSED"
        lines.append(
            f"target per-mission form / batched without Params: {gain:.0f}x (target >= 100x): {met}"
        )
    if "sweep-engine" in found and "sweep-api" in found:
        share = found["sweep-engine"] / found["sweep-api"]
        lines.append(f"share of the API sweep's CPU in the engine + summaries: {share:.0%}")
    return lines


EXECUTORS = ("inprocess", "process", "dask-local")
SCALE_WORKERS = 2


def _subprocess_json(*args: str, src: Path) -> dict[str, float]:
    env = {**os.environ, "PYTHONPATH": str(src)}
    command = [sys.executable, __file__, *args]
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed:\n{done.stderr}")
    result: dict[str, float] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def _scale_line(executor: str, result: dict[str, float]) -> str:
    n = int(result["missions"])
    return (
        f"scale {executor:<10} {n:>10,} missions: wall {result['wall_s']:8.1f} s, "
        f"CPU {result['cpu_s']:8.1f} s ({1e6 * result['cpu_s'] / n:5.0f} us/mission, "
        f"{result['main_cpu_s']:7.1f} s in main), peak RSS {result['peak_b'] / 2**20:5.0f} MiB "
        f"(load {os.getloadavg()[0]:.1f})"
    )


def _report_line(missions: int, result: dict[str, float]) -> str:
    return (
        f"report {missions:>10,} missions: wall {result['wall_s']:6.1f} s, "
        f"CPU {result['cpu_s']:6.1f} s, peak RSS {result['peak_b'] / 2**20:5.0f} MiB "
        f"(target: under 60 s; load {os.getloadavg()[0]:.1f})"
    )


def _scale_row(n: int, executor: str, result: dict[str, float]) -> list[str]:
    """A sweep-scale table row (``executor`` "`skymule report` of it" for a report)."""
    load = f"{os.getloadavg()[0]:.1f}"
    mib = f"{result['peak_b'] / 2**20:.0f}"
    wall, cpu = f"{result['wall_s']:.1f}", f"{result['cpu_s']:.1f}"
    if "main_cpu_s" not in result:  # the report of a sweep
        return [f"{n:,}", executor, wall, cpu, "", "", mib, load]
    per = f"{1e6 * result['cpu_s'] / n:.0f}"
    return [f"{n:,}", executor, wall, cpu, f"{result['main_cpu_s']:.1f}", per, mib, load]


SCALE_COLUMNS = [
    "missions", "executor", "wall [s]", "CPU [s]", "of which the sweep process [s]",
    "CPU per mission [µs]", "peak RSS [MiB]", "load",
]  # fmt: skip


def run_scale(args: argparse.Namespace, src: Path) -> list[list[str]]:
    """``--missions``: each size on each executor, in a fresh process each; the targets.
    Returns the sweep-scale table's rows."""
    rows = []
    sizes = [int(float(n)) for n in args.missions.split(",")]
    executors = [e.strip() for e in args.executors.split(",") if e.strip()]
    results: dict[tuple[int, str], dict[str, float]] = {}
    with contextlib.ExitStack() as stack:
        keep = (
            Path(args.keep)
            if args.keep
            else Path(stack.enter_context(tempfile.TemporaryDirectory()))
        )
        for n in sizes:
            for executor in executors:
                out = keep / f"sweep-{n}-{executor}"
                result = _subprocess_json("--one-sweep", str(n), executor, str(out), src=src)
                results[n, executor] = result
                print(_scale_line(executor, result), flush=True)
                rows.append(_scale_row(int(result["missions"]), executor, result))
        if args.report:
            largest = max(sizes)
            folder = keep / f"sweep-{largest}-{executors[0]}"
            report = _subprocess_json("--one-report", str(folder), src=src)
            print(_report_line(largest, report))
            rows.append(_scale_row(largest, "`skymule report` of it", report))
    inprocess = {n: r for (n, e), r in results.items() if e == "inprocess"}
    if 20_000 in inprocess and 200_000 in inprocess:
        grown = (inprocess[200_000]["peak_b"] - inprocess[20_000]["peak_b"]) / 2**20
        print(f"peak RSS, 200,000 - 20,000 missions (inprocess): {grown:+.0f} MiB (target <= 60)")
    for n in sizes:
        if (n, "dask-local") in results and (n, "inprocess") in results:
            ratio = results[n, "dask-local"]["cpu_s"] / results[n, "inprocess"]["cpu_s"]
            print(f"dask-local CPU / inprocess CPU, {n:,} missions: {ratio:.2f} (target <= 1.15)")
    if 100_000 in inprocess:
        base = inprocess[100_000]["cpu_s"] / inprocess[100_000]["missions"]
        for n, result in sorted(inprocess.items()):
            if n > 100_000:
                ratio = result["cpu_s"] / result["missions"] / base
                print(f"CPU per mission, {n:,} / 100,000 missions: {ratio:.2f} (target <= 1.1)")
    return rows


def main() -> None:
    json_path = json_option()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--one", choices=sorted(CASES), help=argparse.SUPPRESS)
    parser.add_argument("--one-sweep", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("--one-report", help=argparse.SUPPRESS)
    parser.add_argument("--old-rev", help="also run the cases on this git revision")
    parser.add_argument("--old-large", action="store_true", help="previous code at 100k too")
    parser.add_argument("--quick", action="store_true", help="skip the 100k case")
    parser.add_argument("--missions", help="scale mode: sweep sizes, e.g. 20000,200000")
    parser.add_argument("--executors", default=",".join(EXECUTORS), help="scale mode")
    parser.add_argument("--report", action="store_true", help="scale mode: time the report")
    parser.add_argument("--keep", help="scale mode: keep the sweep folders in this folder")
    parser.add_argument("--report-only", help="time the report of this sweep folder")
    parser.add_argument("--one-path", choices=sorted(PATHS), help=argparse.SUPPRESS)
    parser.add_argument("--paths", action="store_true", help="only the issue-33 path rows")
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(args.one)))
        return
    if args.one_sweep:
        n, executor, out = args.one_sweep
        text = SAMPLE.format(n=int(n) // 2)
        workers = None if executor == "inprocess" else SCALE_WORKERS
        print(json.dumps(measure_sweep(text, executor, workers, Path(out))))
        return
    if args.one_report:
        print(json.dumps(measure_report(Path(args.one_report))))
        return
    repo = Path(__file__).resolve().parents[1]
    if args.one_path:
        src = Path(os.environ.get("PYTHONPATH", str(repo / "src")).split(os.pathsep)[0])
        print(json.dumps({"value": measure_path(args.one_path, src)}))
        return
    if args.report_only:
        folder = Path(args.report_only)
        result = _subprocess_json("--one-report", str(folder), src=repo / "src")
        print(_report_line(_missions_in(folder), result))
        return
    if args.missions:
        rows = run_scale(args, repo / "src")
        write(json_path, {"sweep-scale": table(SCALE_COLUMNS, rows, align="rlrrrrrr")}, merge_on=2)
        return
    old_results: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as old_tree:
        if args.old_rev:
            archive = subprocess.run(
                ["git", "-C", str(repo), "archive", args.old_rev],
                capture_output=True,
                check=True,
            ).stdout
            subprocess.run(["tar", "-x", "-C", old_tree], input=archive, check=True)
        if args.paths:
            run_paths(repo / "src", Path(old_tree) / "src" if args.old_rev else None)
            return
        results: dict[str, dict[str, float]] = {}
        for case in CASES:
            large = case.endswith("100k")
            if (args.quick or size(False, True)) and large:
                continue
            results[case] = run_case(case, repo / "src")
            old = None
            if args.old_rev and (not large or args.old_large):
                old = old_results[case] = run_case(case, Path(old_tree) / "src")
            print(_line(case, results[case], old), flush=True)
        run_paths(repo / "src", Path(old_tree) / "src" if args.old_rev else None)
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
    rows = speed_rows(results, old_results, args.old_rev)
    write(json_path, {"speed-sweep": table(["what", "figure", "command"], rows, align="lll")})
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


def speed_rows(
    new: dict[str, dict[str, float]], old: dict[str, dict[str, float]], revision: str | None
) -> list[list[str]]:
    """The speed table's sweep rows from the cases measured now (and on ``revision``)."""
    small, seeds = new["sample-10k"], new["seeds-10k"]
    per = 1e6 * small["cpu_s"] / small["missions"]
    previous = ""
    if "sample-10k" in old:
        before = old["sample-10k"]["cpu_s"]
        previous = (
            f" (previous implementation ({revision}) in the same run: {before:.1f} s, "
            f"**×{before / small['cpu_s']:.1f}**)"
        )
    command = "`python benchmarks/bench_sweep.py" + (f" --old-rev {revision}`" if revision else "`")
    rows = [
        [
            f"sweep, {int(small['missions']):,} missions (paper-sim-fixed × {{greedy, hgad}}, "
            "random buffers), in-process",
            f"{small['cpu_s']:.1f} s CPU, {per:.0f} µs per mission{previous}, peak RSS "
            f"{small['peak_b'] / 2**20:.0f} MiB",
            command,
        ]
    ]
    if "sample-100k" in new:
        large = new["sample-100k"]
        large_per = 1e6 * large["cpu_s"] / large["missions"]
        rows.append(
            [
                f"sweep, {int(large['missions']):,} missions, in-process",
                f"{large_per:.0f} µs CPU per mission ({large_per / per:.2f}× the "
                f"{int(small['missions']):,}-mission cost), peak RSS "
                f"{large['peak_b'] / 2**20:.0f} MiB",
                "same",
            ]
        )
    seed_text = f"{seeds['cpu_s']:.1f} s CPU: {seeds['cpu_s'] / small['cpu_s']:.2f}× the same "
    seed_text += "sweep without a seed axis"
    if "seeds-10k" in old and "sample-10k" in old:
        ratio = old["seeds-10k"]["cpu_s"] / old["sample-10k"]["cpu_s"]
        seed_text += f" (previous: {old['seeds-10k']['cpu_s']:.1f} s, {ratio:.1f}×)"
    rows.append(
        [
            f"sweep over 5,000 seeds (policy × seed, {int(seeds['missions']):,} missions)",
            seed_text,
            "same",
        ]
    )
    scale = "100k" if "process-100k" in new else "10k"
    if f"process-{scale}" in new:
        alone, proc = new[f"sample-{scale}"], new[f"process-{scale}"]
        ideal = alone["cpu_s"] / max(proc["main_cpu_s"], proc["cpu_s"] / 2)
        rows.append(
            [
                "sweep, `process` executor, 2 workers",
                f"{int(proc['missions']):,} missions: **×{alone['wall_s'] / proc['wall_s']:.2f}** "
                f"in-process wall time (load {os.getloadavg()[0]:.1f} on {os.cpu_count()} "
                f"cores); the sweep process uses {proc['main_cpu_s']:.1f} s of the "
                f"{proc['cpu_s']:.1f} s CPU, so two idle cores allow ×{ideal:.2f}",
                "same",
            ]
        )
    return rows


if __name__ == "__main__":
    main()

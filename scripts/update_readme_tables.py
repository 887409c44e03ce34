"""Rewrite the README's measured tables from the output of the commands that measure them.

Run from the repository root: ``python scripts/update_readme_tables.py [options]``.

Every measured table of README.md sits between ``<!-- table:NAME -->`` and ``<!-- /table -->``.
For each table this script runs the commands it quotes (the benchmarks in ``benchmarks/``, the
``skymule`` commands of the results tables), parses what they print or write, and replaces the
lines between the markers, so the numbers cannot drift from what runs here. Text outside the
markers is never touched.

Options:
  --only NAME[,NAME]  regenerate these tables only (names below)
  --all               also run the slow rows (100,000-mission sweep, the whole test suite)
  --check             write nothing; exit 1 if a table would change (timings always change:
                      use it for the deterministic tables, e.g. --only presets,sources)
  --benches A,B       speed table: re-run only these benchmarks (e.g. bench_bound.py);
                      the other rows keep their text
  --tiny              benchmarks at their tiny size (SKYMULE_BENCH_TINY=1): not measurements,
                      for testing this script
  --readme PATH       the file to rewrite (default: README.md next to scripts/)
  --saved FILE[,FILE] sweep-scale table: parse these saved outputs of
                      `bench_sweep.py --missions ...` (runs too long to repeat here)
                      instead of re-running its default sizes; learned table: a saved
                      output of `bench_learned.py` instead of running it

Tables, what they run and roughly how long on the 2-core machine they were written on:
  presets       skymule compare {paper-sim-fixed, aadm-default} --policies greedy,hgad   ~3 s
  autonomous    skymule compare paper-sim-autonomous                                     ~2 s
  table-ii      skymule run paper-sim-autonomous with the paper's Table II buffers (x4)  ~4 s
  sources       skymule compare paper-sim-fixed --sources fspl,two-ray,al-hourani,...    ~3 s
  bounds        skymule compare {paper-sim-fixed, aadm-default} --policies ...,optimal-fixed ~5 s
  planner       skymule compare paper-sim-autonomous --policies hgad,planner (x3 variants) ~10 s
  sweep-example skymule sweep examples/sweep-paper.toml (1,000 missions)                 ~10 s
  sweep-scale   benchmarks/bench_sweep.py --missions 20000,200000 (inprocess) and
                --missions 100000 (inprocess, process, dask-local)                       ~5 min
                (--saved FILE[,FILE]: only the rows of saved outputs of longer runs,
                e.g. --missions 10000000 --report; rows not re-run keep their text)
  sim2real      benchmarks/bench_sim2real.py (3 synthetic worlds, every map, two splits)  ~15 min
  speed         benchmarks/bench_{engine,sweep,channel,bound,autonomous,planner,startup}.py ~15 min
                (SPEED_BENCHES; sweeps and planner against PREVIOUS_REV in the same run;
                the 100,000-mission sweep only with --all: +10 min)
  learned       benchmarks/bench_learned.py: learned vs greedy, hgad, planner, bound on 200
                held-out missions per row, with and without faults                      ~25 min
                (--saved FILE: parse a saved run of it instead of running it)
  suite         python -m pytest -q (only with --all)                                     ~3 min
Rows that are not re-run keep their current text.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
BEGIN = "<!-- table:{name} -->"
END = "<!-- /table -->"


@dataclass(frozen=True)
class Context:
    """Where and how the commands run."""

    work: Path  # scratch folder for output folders
    tiny: bool
    slow: bool
    benches: frozenset[str] = frozenset()  # speed table: only these benchmarks (empty: all)
    saved: tuple[Path, ...] = ()  # sweep-scale table: saved bench_sweep.py --missions outputs

    def run(self, *command: str) -> tuple[str, float]:
        """Run ``command`` from the repository root; (stdout, wall seconds). Fails loudly."""
        env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
        if self.tiny:
            env["SKYMULE_BENCH_TINY"] = "1"
        start = time.perf_counter()
        done = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
        seconds = time.perf_counter() - start
        if done.returncode:
            output = (done.stdout + done.stderr)[-4000:]
            raise SystemExit(f"{' '.join(command)} failed ({done.returncode}):\n{output}")
        return done.stdout, seconds

    def skymule(self, *args: str) -> tuple[str, float]:
        main = "import sys; from skymule.cli import main; sys.exit(main(sys.argv[1:]))"
        return self.run(sys.executable, "-c", main, *args)

    def bench(self, name: str, *args: str) -> str:
        return self.run(sys.executable, f"benchmarks/{name}", *args)[0]


# --------------------------------------------------------------------------- tables


def markdown(header: list[str], align: list[str], rows: list[list[str]]) -> list[str]:
    """A GitHub markdown table; ``align`` holds ``l`` or ``r`` per column."""
    rule = "|" + "|".join("---:" if a == "r" else "---" for a in align) + "|"
    lines = ["| " + " | ".join(cells) + " |" for cells in [header, *rows]]
    return [lines[0], rule, *lines[1:]]


def _compare(ctx: Context, name: str, *args: str) -> pd.DataFrame:
    out = ctx.work / name
    ctx.skymule("compare", *args, "--out", str(out))
    return pd.read_csv(out / "comparison.csv")


def presets_table(ctx: Context, old: list[str]) -> list[str]:
    rows = []
    for preset in ("paper-sim-fixed", "aadm-default"):
        table = _compare(ctx, preset, preset, "--policies", "greedy,hgad")
        for _, r in table.iterrows():
            rows.append(
                [
                    preset,
                    r["policy"],
                    f"{r['total_downloaded_mbit']:.1f}",
                    f"{r['completion']:.3f}",
                    f"{r['handovers']:.0f}",
                    f"{r['hover_time_s']:.0f}",
                    f"{r['distance_m']:.0f}",
                ]
            )
    header = ["preset", "policy", "downloaded [Mbit]", "completion", "handovers", "hover [s]"]
    return markdown([*header, "distance [m]"], list("llrrrrr"), rows)


def autonomous_table(ctx: Context, old: list[str]) -> list[str]:
    table = _compare(ctx, "autonomous", "paper-sim-autonomous")
    rows = [
        [
            r["policy"],
            f"{r['total_downloaded_mbit']:.1f}",
            f"{r['completion']:.3f}",
            f"{r['hover_time_s']:.0f}",
            f"{r['distance_m']:.0f}",
            f"{r['energy_kj']:.1f}",
            f"{r['aadm_score']:.1f}",
        ]
        for _, r in table.iterrows()
    ]
    header = ["policy", "downloaded [Mbit]", "completion", "hover [s]", "distance [m]"]
    return markdown([*header, "energy [kJ]", "AADM score"], list("lrrrrrr"), rows)


SOURCE_LABELS = {"al-hourani": "al-hourani (suburban)"}


def sources_table(ctx: Context, old: list[str]) -> list[str]:
    sources = "fspl,two-ray,al-hourani,3gpp-rma-av"
    table = _compare(ctx, "sources", "paper-sim-fixed", "--sources", sources)
    wide = table.pivot(index="source", columns="policy", values="total_downloaded_mbit")
    rows = [
        [SOURCE_LABELS.get(s, s), f"{wide.loc[s, 'greedy']:.1f}", f"{wide.loc[s, 'hgad']:.1f}"]
        for s in sources.split(",")
    ]
    return markdown(["source", "greedy", "hgad"], list("lrr"), rows)


def sweep_example_table(ctx: Context, old: list[str]) -> list[str]:
    out = ctx.work / "sweep"
    _, seconds = ctx.skymule("sweep", "examples/sweep-paper.toml", "--out", str(out))
    summary = pd.read_csv(out / "summary.csv").set_index("policy")
    missions = int(summary["missions"].sum())
    cells = [
        f"{summary.loc[p, 'total_downloaded_mbit_mean']:.1f} ± "
        f"{summary.loc[p, 'total_downloaded_mbit_ci95']:.1f}"
        for p in ("greedy", "hgad")
    ]
    header = ["missions", "wall time [s]", "greedy [Mbit] (mean ± 95% CI)", "hgad [Mbit]"]
    return markdown(header, list("rrrr"), [[f"{missions:,}", f"{seconds:.1f}", *cells]])


SCALE_RUNS = (
    ("--missions", "20000,200000", "--executors", "inprocess"),
    ("--missions", "100000", "--executors", "inprocess,process,dask-local"),
)
"""The ``bench_sweep.py`` scale runs the sweep-scale table re-measures (~5 min)."""

SCALE_LINE = (
    r"scale (\S+)\s+([\d,]+) missions: wall\s+([\d.]+) s, CPU\s+([\d.]+) s \(\s*(\d+) "
    r"us/mission,\s+([\d.]+) s in main\), peak RSS\s+(\d+) MiB \(load ([\d.]+)\)"
)
REPORT_LINE = (
    r"report\s+([\d,]+) missions: wall\s+([\d.]+) s, CPU\s+([\d.]+) s, peak RSS\s+(\d+) MiB "
    r"\(target: under 60 s; load ([\d.]+)\)"
)


def scale_rows(out: str) -> dict[tuple[str, str], list[str]]:
    """Table rows by (missions, executor) from ``bench_sweep.py --missions`` output."""
    rows = {}
    for executor, n, wall, cpu, us, main, mib, load in re.findall(SCALE_LINE, out):
        key = (f"{int(_f(n)):,}", executor)
        rows[key] = [*key, f"{_f(wall):.1f}", f"{_f(cpu):.1f}", f"{_f(main):.1f}", us, mib, load]
    for n, wall, cpu, mib, load in re.findall(REPORT_LINE, out):
        key = (f"{int(_f(n)):,}", "`skymule report` of it")
        rows[key] = [*key, f"{_f(wall):.1f}", f"{_f(cpu):.1f}", "", "", mib, load]
    return rows


SCALE_HEADER = [
    "missions",
    "executor",
    "wall [s]",
    "CPU [s]",
    "of which the sweep process [s]",
    "CPU per mission [µs]",
]


def sweep_scale_table(ctx: Context, old: list[str]) -> list[str]:
    """Sweeps of 20,000 to 10,000,000 missions per executor; rows measured now replace the
    rows of the same size and executor, the others keep their text."""
    rows: dict[tuple[str, str], list[str]] = {}
    for line in old[2:]:
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == len(SCALE_HEADER) + 2:
            rows[cells[0], cells[1]] = cells
    runs = (
        [("--missions", "40", "--executors", "inprocess", "--report")] if ctx.tiny else SCALE_RUNS
    )
    for args in () if ctx.saved else runs:
        out = ctx.bench("bench_sweep.py", *args)
        print(out, file=sys.stderr)  # the targets' lines too, for the record
        rows.update(scale_rows(out))
    for path in ctx.saved:
        found = scale_rows(path.read_text())
        if not found:
            raise SystemExit(f"--saved {path}: no bench_sweep.py --missions lines in it")
        rows.update(found)
    order = sorted(rows, key=lambda k: (int(k[0].replace(",", "")), k[1].startswith("`"), k[1]))
    header = [*SCALE_HEADER, "peak RSS [MiB]", "load"]
    return markdown(header, list("rlrrrrrr"), [rows[k] for k in order])


def _bound_mbit(out: Path) -> tuple[float, float | None]:
    """(bound, no-hover bound) [Mbit] of a compare folder's bound.json."""
    record = json.loads((out / "bound.json").read_text())
    return record["upper_bound_mbit"], record["no_hover_upper_bound_mbit"]


def bounds_table(ctx: Context, old: list[str]) -> list[str]:
    """The bound and each policy's gap to it on the fixed presets."""
    rows = []
    for preset in ("paper-sim-fixed", "aadm-default"):
        name = f"bounds-{preset}"
        table = _compare(ctx, name, preset, "--policies", "greedy,hgad,optimal-fixed")
        bound, no_hover = _bound_mbit(ctx.work / name)
        cells = [preset, f"{bound:.1f} ({no_hover:.1f})"]
        for i, (_, r) in enumerate(table.iterrows()):
            gap = f"{100 * r['gap_to_bound_frac']:.2f}%"
            cells.append(f"{r['total_downloaded_mbit']:.1f} ({'gap ' if i == 0 else ''}{gap})")
        rows.append(cells)
    header = ["preset", "bound [Mbit] (no hover)", "greedy", "hgad", "optimal-fixed"]
    return markdown(header, list("lrrrr"), rows)


PLANNER_CASES = (
    ("paper-sim-autonomous", ()),
    ("same, 300 s", ("--set", "mission.duration_s=300")),
    (
        "same, 1500 Mbit per tower",
        tuple(a for i in range(4) for a in ("--set", f"sensors[{i}].buffer_mbit=1500")),
    ),
)


def planner_table(ctx: Context, old: list[str]) -> list[str]:
    """HGAD and the planner against the autonomous bound: as specified, shorter, larger."""
    rows = []
    for label, args in PLANNER_CASES:
        name = f"planner-{len(rows)}"
        table = _compare(ctx, name, "paper-sim-autonomous", "--policies", "hgad,planner", *args)
        cells = [label]
        for _, r in table.iterrows():
            down = r["total_downloaded_mbit"]
            if r["aadm_complete"]:  # everything downloaded: when, and the score it earns
                cells.append(
                    f"{down:.1f} Mbit, done at {r['aadm_t1_s']:.0f} s, AADM {r['aadm_score']:.0f}"
                )
            else:
                cells.append(f"{down:.1f}")
        rows.append([*cells, f"{_bound_mbit(ctx.work / name)[0]:.1f}"])
    return markdown(["autonomous", "hgad", "planner", "bound"], list("lrrr"), rows)


TABLE_II = (
    ((700, 500, 800, 1000), "LW4, LW3, LW1, LW2"),
    ((500, 800, 1000, 700), "LW3, LW2, LW4, LW1"),
    ((800, 500, 700, 1000), "LW4, LW1, LW3, LW2"),
    ((500, 1000, 700, 800), "LW2, LW4, LW3, LW1"),
)
"""The paper's Table II: buffers LW1..LW4 [Mbit] and HGAD's navigation order (published)."""


def table_ii_table(ctx: Context, old: list[str]) -> list[str]:
    """HGAD's visit order on paper-sim-autonomous for the paper's Table II buffers."""
    rows = []
    for buffers, paper in TABLE_II:
        sets = [
            a for i, b in enumerate(buffers) for a in ("--set", f"sensors[{i}].buffer_mbit={b}")
        ]
        out, _ = ctx.skymule("run", "paper-sim-autonomous", "--policy", "hgad", *sets, "--json")
        order = ", ".join(json.loads(out)["visit_order"])
        rows.append(["/".join(map(str, buffers)), paper, order])
    return markdown(["buffers LW1..LW4 [Mbit]", "paper", "skymule"], list("lll"), rows)


def _numbers(pattern: str, text: str) -> list[tuple[str, ...]]:
    found = re.findall(pattern, text)
    if not found:
        raise SystemExit(f"expected output matching {pattern!r}, got:\n{text}")
    return [f if isinstance(f, tuple) else (f,) for f in found]


def _f(text: str) -> float:
    return float(text.replace(",", ""))


def _m(text: str) -> float:
    return _f(text) / 1e6


PREVIOUS_REV = "4ddfba8"
"""The last revision before the one engine (scalar reference engines beside fused batched
ones): the speed rows' "previous" figures (``bench_autonomous.py --reference-rev``,
``bench_sweep.py --old-rev``, ``bench_planner.py --before``) are measured against it in the
same benchmark run. (Revisions, not tags: a fresh clone has no tags.)"""


def engine_cells(out: str) -> dict[str, str]:
    """One mission at a time, the numpy slot loop and the compiled twin, from
    ``bench_engine.py``."""
    rate = {
        (policy, label.strip()): _f(value)
        for policy, label, value in _numbers(
            r"(greedy|hgad)\s+(single|numpy loop|numpy \+ summaries|compiled loop|"
            r"compiled \+ summaries)[^\n]*?\s([\d.]+) M",
            out,
        )
    }
    (written,), *_ = _numbers(r"bytes written per mission-slot: (\d+)", out)
    (bandwidth,), *_ = _numbers(r"memory bandwidth .*?: ([\d.]+) GB/s", out)
    cells = {
        "^one mission at a time": (
            f"{rate['greedy', 'single']:.2f} M (Greedy) / {rate['hgad', 'single']:.2f} M (HGAD) "
            "mission-slots per CPU-s"
        ),
        "^engine, numpy slot loop": (
            f"Greedy {rate['greedy', 'numpy + summaries']:.1f} M mission-slots/CPU-s with "
            f"summaries ({rate['greedy', 'numpy loop']:.1f} M slot loop only), HGAD "
            f"{rate['hgad', 'numpy + summaries']:.1f} M ({rate['hgad', 'numpy loop']:.1f} M)"
        ),
    }
    compiled = []
    for policy, name in (("greedy", "Greedy"), ("hgad", "HGAD")):
        loop, summaries = rate[policy, "compiled loop"], rate[policy, "compiled + summaries"]
        ratio = summaries / rate[policy, "numpy + summaries"]
        compiled.append(
            f"{name} {summaries:.1f} M with summaries (**×{ratio:.1f}** numpy), {loop:.1f} M loop"
        )
    cells["^engine, compiled twin"] = (
        f"{'; '.join(compiled)}; {written} bytes written per mission-slot against "
        f"{_f(bandwidth):.1f} GB/s measured memory bandwidth"
    )
    return cells


def policies_cells(out: str) -> dict[str, str]:
    """Your own policy, batched and per-mission, from ``bench_policies.py``."""
    ((fixed_rate,),) = _numbers(r"fixed \(.*?\+ summaries: ([\d.]+) M mission-slots", out)
    ((auto_rate,),) = _numbers(r"autonomous \(.*?\+ summaries: ([\d,]+) missions per", out)
    forms = _numbers(
        r"per-mission form, one mission at a time: ([\d.]+) ms per mission; batched ([\d.]+) "
        r"us per mission: (\d+)x less \(target >= 100\); totals equal: (\w+)",
        out,
    )
    (f_ms, f_us, f_x, f_same), (a_ms, a_us, a_x, a_same) = forms
    costs = {
        (mode, where): _f(us)
        for mode, where, us in _numbers(
            r"(fixed|autonomous), per-mission policy: engine overhead beyond act, a batch of "
            r"([\d,]+|one): ([\d.]+) us per slot",
            out,
        )
    }
    batch = next(where for mode, where in costs if where != "one")
    return {
        "^your own batched policy, fixed": (
            f"{_f(fixed_rate):.1f} M mission-slots per CPU-s with summaries; the per-mission "
            f"form one mission at a time {_f(f_ms):.1f} ms a mission, **×{f_x}** the batched "
            f"form's {_f(f_us):.0f} µs; totals equal: {f_same.lower()}"
        ),
        "^your own batched policy, autonomous": (
            f"{_f(auto_rate):,.0f} missions per CPU-s with summaries; the per-mission form one "
            f"at a time {_f(a_ms):.0f} ms a mission, **×{a_x}** the batched form's "
            f"{_f(a_us):.0f} µs; totals equal: {a_same.lower()}"
        ),
        "^your own per-mission policy": (
            f"fixed {costs['fixed', batch]:.1f} µs in a batch of {batch} "
            f"({costs['fixed', 'one']:.0f} µs alone); autonomous "
            f"{costs['autonomous', batch]:.1f} µs ({costs['autonomous', 'one']:.0f} µs alone)"
        ),
    }


def sweep_cells(out: str) -> dict[str, str]:
    """Sweep rows from ``bench_sweep.py --old-rev PREVIOUS_REV`` (100k only with --all)."""
    line = r"(\S+)\s+(\d+) missions:\s+([\d.]+) s CPU .*?(\d+) us CPU/mission, peak\s+(\d+) MiB"
    cases = {
        case: (int(n), _f(cpu), int(us), int(mib)) for case, n, cpu, us, mib in _numbers(line, out)
    }
    # "| previous ..." only with --old-rev
    previous = dict(re.findall(r"(\S+)\s+\d+ missions:.*\| previous\s+([\d.]+) s CPU", out))
    cells = {}
    _, cpu, us, mib = cases["sample-10k"]
    old = f"previous implementation ({PREVIOUS_REV}) in the same run: "
    if "sample-10k" in previous:
        old += f"{_f(previous['sample-10k']):.1f} s, **×{_f(previous['sample-10k']) / cpu:.1f}**"
    cells["^sweep, 10,000 missions"] = (
        f"{cpu:.1f} s CPU, {us} µs per mission ({old}), peak RSS {mib} MiB"
    )
    seeds = cases["seeds-10k"]
    cells["^sweep over 5,000 seeds"] = (
        f"{seeds[1]:.1f} s CPU: {seeds[1] / cpu:.2f}× the same sweep without a seed axis"
        + (
            f" (previous: {_f(previous['seeds-10k']):.1f} s, "
            f"{_f(previous['seeds-10k']) / _f(previous['sample-10k']):.1f}×)"
            if "seeds-10k" in previous and "sample-10k" in previous
            else ""
        )
    )
    scale = "100k" if "process-100k" in cases else "10k"
    ((wall_ratio, load, ideal, main_s, all_s),) = [
        row
        for row in _numbers(
            rf"process executor, 2 workers, {scale}: ([\d.]+)x in-process in wall time "
            r"\(target >= 1.7; load ([\d.]+) .*?\), ([\d.]+)x on two idle cores from the CPU "
            r"split \(main ([\d.]+) s, all ([\d.]+) s\)",
            out,
        )
    ]
    cells["^sweep, `process` executor"] = (
        f"{scale.replace('k', ',000')} missions: **×{_f(wall_ratio):.2f}** in-process wall time "
        f"(load {_f(load):.1f} on 2 cores); the sweep process uses {_f(main_s):.1f} s of the "
        f"{_f(all_s):.1f} s CPU, so two idle cores allow ×{_f(ideal):.2f}"
    )
    if "sample-100k" in cases:
        large = cases["sample-100k"]
        cells["^sweep, 100,000 missions"] = (
            f"{large[2]} µs CPU per mission ({large[2] / us:.2f}× the 10,000-mission cost), "
            f"peak RSS {large[3]} MiB"
        )
    return cells


def channel_cells(out: str) -> dict[str, str]:
    (fspl,), *_ = _numbers(r"\n  fspl\s+([\d.]+)", out)
    (draw, query, total), *_ = _numbers(r"field draw ([\d.]+), query ([\d.]+), total ([\d.]+)", out)
    return {
        "^SNR, 4 sensors": (
            f"{_f(total):.2f} s (field draw {_f(draw):.2f} s + query {_f(query):.2f} s); "
            f"fspl alone {_f(fspl):.2f} s"
        )
    }


def bound_cells(out: str) -> dict[str, str]:
    """The three scale cases of ``bench_bound.py`` (column generation vs every column)."""
    found = _numbers(
        r"bound (\d+) slots x (\d+) sensors \(hover\): column generation ([\d.]+) s CPU.*?"
        r"previous \(every column\) ([\d.]+) s -> x[\d.]+, bounds differ by ([\d.e+-]+)",
        out,
    )
    new = " / ".join(f"{_f(cg):.2f} s" for _, _, cg, _, _ in found)
    old = " / ".join(f"{_f(full):.2f} s" for _, _, _, full, _ in found)
    what = " / ".join(f"{int(slots):,} × {sensors}" for slots, sensors, _, _, _ in found)
    worst = max(abs(_f(d)) for *_, d in found)
    return {
        "^fixed-path bound": (
            f"{what}: {new} CPU (every-column LPs in the same run: {old}); bounds differ by at "
            f"most {worst:.0e} (relative)"
        )
    }


def autonomous_cells(out: str) -> dict[str, str]:
    """One at a time, the previous reference engine and the batched sweep path, from
    ``bench_autonomous.py --reference-rev``."""
    lines = out.split("batched engine (summaries)")
    single = {p: _f(m) for p, m in _numbers(r"(?m)^  (greedy|hgad)\s+([\d.]+) missions,", lines[0])}
    head = lines[0].split("previous reference engine")
    single = {p: _f(m) for p, m in _numbers(r"(?m)^  (greedy|hgad)\s+([\d.]+) missions,", head[0])}
    previous = {}
    if len(head) > 1:
        previous = {
            p: _f(m) for p, m in _numbers(r"(?m)^  (greedy|hgad)\s+([\d.]+) missions", head[1])
        }
    batched = {
        (p, engine): (_f(m), _f(x))
        for p, m, x, engine in _numbers(
            r"(?m)^  (greedy|hgad)\s+([\d.]+) missions,\s+[\d,]+ mission-slots,\s+([\d.]+)x "
            r"one at a time.*?\((numpy|compiled)",
            lines[1],
        )
    }
    cells = {
        "^autonomous missions, one at a time": (
            f"Greedy {single['greedy']:.0f}, HGAD {single['hgad']:.0f} missions per CPU-s"
            + (
                f" (the previous reference engine, {PREVIOUS_REV}, in the same run: Greedy "
                f"{previous['greedy']:.0f}, HGAD {previous['hgad']:.0f})"
                if previous
                else ""
            )
        ),
    }
    for engine in ("numpy", "compiled"):
        if ("greedy", engine) not in batched:
            continue
        parts = []
        for name, label in (("greedy", "Greedy"), ("hgad", "HGAD")):
            rate, ratio = batched[name, engine]
            old = f", **×{rate / previous[name]:.0f}** the previous reference" if previous else ""
            parts.append(
                f"{label} {rate:,.0f} missions per CPU-s (×{ratio:.0f} one at a time{old})"
            )
        cells[f"^autonomous missions, batched, {engine}"] = "; ".join(parts)
    return cells


def planner_cells(out: str) -> dict[str, str]:
    ((before,),) = _numbers(r"before \(.*?\): ([\d.]+)", out)
    ((now, same, total),) = _numbers(
        r"\n  now: ([\d.]+)  x[\d.]+, identical logs: (\d+) of (\d+)", out
    )
    ((plain,),) = _numbers(r"no numba\): ([\d.]+)", out)
    return {
        "^planner": (
            f"{_f(now):.1f} missions per CPU-s ({PREVIOUS_REV} in the same run: {_f(before):.1f}, "
            f"×{_f(now) / _f(before):.1f}; {_f(plain):.1f} without numba); identical plans in "
            f"{same} of {total} missions"
        )
    }


def startup_cells(out: str) -> dict[str, str]:
    """Start-up of ``skymule --help``, ``run``, ``bound`` and ``compare`` of a preset, from
    ``bench_startup.py`` (wall and CPU medians; the target is 3x ``--help``)."""
    ((runs, load),) = _numbers(r"median of (\d+) runs \(load ([\d.]+) ->", out)
    found = {
        label: (_f(wall), _f(cpu))
        for label, wall, cpu in _numbers(
            r"(?m)^  (--help|run|bound|compare)\s+wall\s+([\d.]+) s \(min [\d.]+\), CPU ([\d.]+) s",
            out,
        )
    }
    help_wall, help_cpu = found["--help"]
    parts = [f"`--help` {help_wall:.2f} s ({help_cpu:.2f} s CPU)"]
    parts += [
        f"`{label}` {wall:.2f} s (×{wall / help_wall:.1f}; {cpu:.2f} s CPU, ×{cpu / help_cpu:.1f})"
        for label, (wall, cpu) in found.items()
        if label != "--help"
    ]
    return {"^start-up": f"{', '.join(parts)}; median of {runs}, load {_f(load):.1f} on 2 cores"}


SPEED_BENCHES: dict[str, tuple[tuple[str, ...], Callable[[str], dict[str, str]]]] = {
    "bench_engine.py": ((), engine_cells),
    "bench_sweep.py": (("--old-rev", PREVIOUS_REV), sweep_cells),
    "bench_channel.py": ((), channel_cells),
    "bench_bound.py": ((), bound_cells),
    "bench_autonomous.py": (("--reference-rev", PREVIOUS_REV), autonomous_cells),
    "bench_policies.py": ((), policies_cells),
    "bench_planner.py": (("--speed", "20", "--before", PREVIOUS_REV), planner_cells),
    "bench_startup.py": ((), startup_cells),
}
"""Benchmark -> (its arguments for the README, the parser of its output into speed cells).
``tests/test_benchmarks_smoke.py`` feeds each parser the tiny run's output, so none rots."""


def speed_rows(ctx: Context) -> dict[str, str]:
    """The ``figure`` cell of every speed row, by a pattern of its ``what`` cell."""
    cells: dict[str, str] = {}
    for name, (args, parse) in SPEED_BENCHES.items():
        if ctx.benches and name not in ctx.benches:
            continue
        if name == "bench_sweep.py" and not ctx.slow:
            args = (*args, "--quick")
        if ctx.tiny and name == "bench_planner.py":
            args = ("--speed", "2", "--before", PREVIOUS_REV)
        cells.update(parse(ctx.bench(name, *args)))
    return cells


NEW_SPEED_ROWS = {
    "^start-up": (
        "start-up: `skymule --help`, and `run`, `bound`, `compare` of paper-sim-fixed, wall "
        "time of a fresh process (×: against `--help`)",
        "`python benchmarks/bench_startup.py`",
    ),
}
"""Rows a measured pattern adds when the table has none yet: pattern -> (what, command)."""


def speed_table(ctx: Context, old: list[str]) -> list[str]:
    """Rewrite the figure cell of each row whose ``what`` matches a measured row's pattern;
    a row no benchmark measured this time (the 100k sweep without --all) keeps its text, and
    a measured pattern of :data:`NEW_SPEED_ROWS` that no row matches is added as a row."""
    cells = speed_rows(ctx)
    out = []
    matched = set()
    for line in old:
        parts = line.split(" | ")
        what = parts[0].lstrip("| ")
        key = next((k for k in cells if re.search(k, what)), None)
        if key is not None and len(parts) >= 3:
            parts[1] = cells[key]
            line = " | ".join(parts)
            matched.add(key)
        out.append(line)
    for key, (what, command) in NEW_SPEED_ROWS.items():
        if key in cells and key not in matched:
            out.append(f"| {what} | {cells[key]} | {command} |")
    return out


def suite_table(ctx: Context, old: list[str]) -> list[str]:
    """The whole suite's counts and wall time (only with --all; failures are reported, not
    hidden: the row says how many failed)."""
    if not ctx.slow or ctx.tiny:
        return old
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    seconds = time.perf_counter() - start
    tail = done.stdout.strip().splitlines()[-1] if done.stdout.strip() else ""
    counts = {kind: int(n) for n, kind in re.findall(r"(\d+) (passed|skipped|failed)", tail)}
    if not counts:
        raise SystemExit(f"pytest printed no summary line:\n{done.stdout[-3000:]}")
    return markdown(
        ["tests", "passed", "skipped", "failed", "wall time [s]", "command"],
        list("rrrrrl"),
        [
            [
                str(sum(counts.values())),
                str(counts.get("passed", 0)),
                str(counts.get("skipped", 0)),
                str(counts.get("failed", 0)),
                f"{seconds:.0f}",
                "`python -m pytest -q`",
            ]
        ],
    )


def _fields(line: str) -> dict[str, str]:
    return dict(part.split("=", 1) for part in line.split()[1:])


def learned_table(ctx: Context, old: list[str]) -> list[str]:
    """The learned policy against the others, per fault condition and sensor count, and its
    speed, from ``bench_learned.py`` (or its saved output)."""
    saved = [path.read_text() for path in ctx.saved]
    out = next((text for text in saved if "vs-hgad: " in text), None)
    if out is None:
        out = ctx.bench("bench_learned.py")
    rows = [_fields(line) for line in out.splitlines() if line.startswith("row: ")]
    versus = [_fields(line) for line in out.splitlines() if line.startswith("vs-hgad: ")]
    if not rows or not versus:
        raise SystemExit(f"bench_learned.py printed no row:/vs-hgad: lines:\n{out[-3000:]}")
    cell = {(r["condition"], r["n"], r["policy"]): r for r in rows}
    table = []
    for v in versus:
        key = (v["condition"], v["n"])

        def mean(policy: str, key: tuple[str, str] = key) -> str:
            r = cell[(*key, policy)]
            return f"{_f(r['mean']):.1f} ± {_f(r['ci']):.1f}"

        def diff(policy: str, key: tuple[str, str] = key) -> str:
            r = cell[(*key, policy)]
            return f"{_f(r['diff']):+.1f} ± {_f(r['diff_ci']):.1f}"

        table.append(
            [
                "faults" if v["condition"] == "faults" else "none",
                v["n"],
                v["missions"],
                mean("learned"),
                mean("greedy"),
                mean("hgad"),
                mean("planner"),
                mean("bound"),
                diff("hgad"),
                f"{100 * _f(v['rel']):+.1f}% ± {100 * _f(v['rel_ci']):.1f}",
                f"{100 * _f(v['worst']):+.1f}%, {v['below5']}",
                diff("planner"),
                f"{100 * _f(cell[(*key, 'learned')]['gap']):.1f}%",
            ]
        )
    header = [
        "faults", "N", "missions", "learned", "greedy", "hgad", "planner", "bound",
        "learned − hgad", "vs hgad", "worst vs hgad, missions < −5%", "learned − planner",
        "learned's gap to bound",
    ]  # fmt: skip
    lines = markdown(header, list("lrrrrrrrrrrrr"), table)
    ((per_us, _decisions),) = _numbers(
        r"inference, one mission: ([\d.]+) us CPU per decision.*?(\d+) decisions", out
    )
    ((rate, slots, per_mission),) = _numbers(
        r"batched in the engine, [\d,]+ missions: ([\d,]+) decisions per CPU-s \(([\d,]+) "
        r"mission-slots per CPU-s, engine included; ([\d.]+) decisions per mission\)",
        out,
    )
    ((hgad_slots,),) = _numbers(r"hgad in the same engine: ([\d,]+) mission-slots", out)
    ((batch, scored),) = _numbers(
        r"scorer on a batch of ([\d,]+) decisions \(numpy\): ([\d,]+) decisions per CPU-s", out
    )
    twin = re.findall(r"on a batch of [\d,]+ decisions \(compiled\): ([\d,]+) decisions", out)
    twin_text = f", its compiled twin {_f(twin[0]):,.0f}" if twin else ""  # numba installed
    lines += [
        "",
        f"Speed (same run): one decision of one mission (features and network) "
        f"{_f(per_us):.1f} µs CPU; batched in the engine {_f(rate):,.0f} option decisions per "
        f"CPU-s, i.e. {_f(slots):,.0f} mission-slots (a serve and a goal each) per CPU-s, engine "
        f"included (HGAD {_f(hgad_slots):,.0f}), "
        f"{_f(per_mission):.1f} decisions per mission; the scorer alone on a batch of {batch} "
        f"decisions {_f(scored):,.0f} decisions per CPU-s (numpy){twin_text} "
        "(`python benchmarks/bench_learned.py`).",
    ]
    return lines


SIM2REAL_LINE = re.compile(
    r"^  (?P<map>\S.*?\S)\s{2,}(?P<split>(?:time|flight) \(.*?\))\s+(?P<rmse>[\d.]+)\s+"
    r"(?P<over>[+-][\d.]+)\s+(?P<bias>[+-][\d.]+)\s+(?P<cover>\d+%|n/a)\s+(?P<greedy>\S+)\s+"
    r"(?P<hgad>\S+)\s+(?P<fit>[\d.]+)$",
    re.M,
)


def sim2real_rows(out: str) -> list[list[str]]:
    """The rows of the "mean over N worlds" block of ``bench_sim2real.py``."""
    mean = out.split("mean over", 1)
    if len(mean) < 2:
        raise SystemExit(f"bench_sim2real.py printed no mean block:\n{out[-3000:]}")
    block = mean[1].split("\nlearned twin", 1)[0]
    rows = [
        [m["map"], m["split"], m["rmse"], m["over"], m["bias"], m["cover"],
         m["greedy"], m["hgad"], m["fit"]]
        for m in SIM2REAL_LINE.finditer(block)
    ]  # fmt: skip
    if not rows:
        raise SystemExit(f"bench_sim2real.py: no rows in the mean block:\n{block}")
    return rows


def sim2real_table(ctx: Context, old: list[str]) -> list[str]:
    """Maps and learned twins against a held-out "real" flight, mean over synthetic worlds."""
    rows = sim2real_rows(ctx.bench("bench_sim2real.py"))
    header = ["map", "held out", "SNR RMSE [dB]", "over the noise floor [dB]", "bias [dB]"]
    header += ["in the 95% interval", "Greedy Mbit error", "HGAD Mbit error", "fit CPU [s]"]
    return markdown(header, list("llrrrrrrr"), rows)


TABLES: dict[str, Callable[[Context, list[str]], list[str]]] = {
    "presets": presets_table,
    "autonomous": autonomous_table,
    "table-ii": table_ii_table,
    "sources": sources_table,
    "bounds": bounds_table,
    "planner": planner_table,
    "sweep-example": sweep_example_table,
    "sweep-scale": sweep_scale_table,
    "sim2real": sim2real_table,
    "speed": speed_table,
    "learned": learned_table,
    "suite": suite_table,
}


# --------------------------------------------------------------------------- the file


def table_span(lines: list[str], name: str) -> tuple[int, int]:
    """Indices of the first and last line strictly between the markers of table ``name``."""
    begin = BEGIN.format(name=name)
    try:
        start = lines.index(begin) + 1
        end = lines.index(END, start)
    except ValueError:
        raise SystemExit(f"README has no {begin} ... {END} block") from None
    return start, end


def rewrite(text: str, name: str, make: Callable[[list[str]], list[str]]) -> str:
    """``text`` with the lines of table ``name`` replaced by ``make(old lines)``."""
    lines = text.split("\n")
    start, end = table_span(lines, name)
    return "\n".join([*lines[:start], *make(lines[start:end]), *lines[end:]])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", default=",".join(TABLES))
    parser.add_argument("--all", action="store_true")
    parser.add_argument("--check", action="store_true")
    parser.add_argument("--tiny", action="store_true")
    parser.add_argument("--benches", default="")
    parser.add_argument("--readme", type=Path, default=ROOT / "README.md")
    parser.add_argument("--saved", default="")
    args = parser.parse_args(argv)
    names = [n.strip() for n in args.only.split(",") if n.strip()]
    unknown = [n for n in names if n not in TABLES]
    if unknown:
        parser.error(f"--only {','.join(unknown)}: allowed: {', '.join(TABLES)}")
    original = args.readme.read_text()
    text = original
    with tempfile.TemporaryDirectory() as scratch:
        benches = frozenset(b.strip() for b in args.benches.split(",") if b.strip())
        unknown_benches = sorted(benches - set(SPEED_BENCHES))
        if unknown_benches:
            parser.error(f"--benches {unknown_benches[0]}: allowed: {', '.join(SPEED_BENCHES)}")
        saved = tuple(Path(p.strip()) for p in args.saved.split(",") if p.strip())
        ctx = Context(Path(scratch), args.tiny, args.all, benches, saved)
        for name in names:
            start = time.perf_counter()
            text = rewrite(text, name, lambda old, n=name: TABLES[n](ctx, old))
            print(f"{name}: {time.perf_counter() - start:.0f} s", file=sys.stderr)
    if args.check:
        return int(text != original)
    if text != original:
        args.readme.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

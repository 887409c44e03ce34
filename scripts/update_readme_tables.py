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
  --tiny              benchmarks at their tiny size (SKYMULE_BENCH_TINY=1): not measurements,
                      for testing this script
  --readme PATH       the file to rewrite (default: README.md next to scripts/)

Tables, what they run and roughly how long on the 2-core machine they were written on:
  presets       skymule compare {paper-sim-fixed, aadm-default} --policies greedy,hgad   ~3 s
  autonomous    skymule compare paper-sim-autonomous                                     ~2 s
  sources       skymule compare paper-sim-fixed --sources fspl,two-ray,al-hourani,...    ~3 s
  sweep-example skymule sweep examples/sweep-paper.toml (1,000 missions)                 ~10 s
  speed         benchmarks/bench_{single,engine,sweep,channel,bound,autonomous}.py      ~60 s
                (+ bench_sweep.py 50000 with --all: ~260 s)
  suite         python -m pytest -q (only with --all)                                     ~3 min
Rows that are not re-run keep their current text.
"""

from __future__ import annotations

import argparse
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


def _numbers(pattern: str, text: str) -> list[tuple[str, ...]]:
    found = re.findall(pattern, text)
    if not found:
        raise SystemExit(f"expected output matching {pattern!r}, got:\n{text}")
    return [f if isinstance(f, tuple) else (f,) for f in found]


def _f(text: str) -> float:
    return float(text.replace(",", ""))


def speed_rows(ctx: Context) -> dict[str, str]:
    """The ``figure`` cell of every speed row that is re-measured, by a pattern of its
    ``what`` cell."""
    cells: dict[str, str] = {}
    single = _numbers(
        r"([\d,]+) slots/s \(([\d.]+) ms per (\d+)-slot", ctx.bench("bench_single.py")
    )
    rates = [_f(r) for r, _, _ in single[:2]]  # paper-sim-fixed: greedy, hgad
    ms = [_f(m) for _, m, _ in single[:2]]
    cells["^reference engine"] = (
        f"{min(rates):,.0f}–{max(rates):,.0f} slots/s ({min(ms):.0f}–{max(ms):.0f} ms per "
        f"{single[0][2]}-slot mission)"
    )
    engine = ctx.bench("bench_engine.py")
    for policy, row in (("hgad", "HGAD"), ("greedy", "Greedy")):
        get = {
            label.strip(): (_f(rate), _f(times))
            for label, rate, times in _numbers(
                rf"{policy}\s+(batched, \w+)\s+([\d,]+)\s+\([\d.]+ s\)\s+x(\d+)", engine
            )
        }
        summaries, logs = get["batched, summaries"], get["batched, logs"]
        cells[f"^batched engine.*{row}$"] = (
            f"{summaries[0] / 1e6:.1f} M mission-slots/s with summaries (**×{summaries[1]:.0f}** "
            f"the reference engine in the same run), {logs[0] / 1e6:.1f} M with full logs "
            f"(×{logs[1]:.0f})"
        )
    for layouts, row in ((5000, "^sweep, 10,000 missions"), (50000, "^sweep, 100,000 missions")):
        if layouts > 5000 and not ctx.slow:
            continue
        args = ("5",) if ctx.tiny else (str(layouts),)
        (seconds, rate, rss), *_ = _numbers(
            r"missions \(.*?\): ([\d.]+) s, ([\d,]+) missions/s, peak RSS ([\d,]+) MiB",
            ctx.bench("bench_sweep.py", *args),
        )
        cells[row] = f"{_f(seconds):.1f} s ({rate} missions/s), peak RSS {rss} MiB"
    channel = ctx.bench("bench_channel.py")
    (fspl,), *_ = _numbers(r"\n  fspl\s+([\d.]+)", channel)
    (draw, query, total), *_ = _numbers(
        r"field draw ([\d.]+), query ([\d.]+), total ([\d.]+)", channel
    )
    cells["^SNR, 4 sensors"] = (
        f"{_f(total):.2f} s (field draw {_f(draw):.2f} s + query {_f(query):.2f} s); "
        f"fspl alone {_f(fspl):.2f} s"
    )
    bound = {
        int(slots): _f(s)
        for slots, s in _numbers(
            r"bound (\d+) slots x \d+ sensors \(hover\): ([\d.]+) s", ctx.bench("bench_bound.py")
        )
    }
    small, large = sorted(bound)[0], sorted(bound)[-1]
    cells["^fixed-path bound"] = f"{bound[small]:.2f} s / {bound[large]:.1f} s"
    per_run = [_f(s) for (s,) in _numbers(r" ([\d.]+)  order ", ctx.bench("bench_autonomous.py"))]
    cells["^autonomous mission"] = f"{min(per_run):.2f}–{max(per_run):.2f} s"
    return cells


def speed_table(ctx: Context, old: list[str]) -> list[str]:
    """Rewrite the figure cell of each row whose ``what`` matches a measured row's pattern."""
    cells = speed_rows(ctx)
    out = []
    for line in old:
        parts = line.split(" | ")
        what = parts[0].lstrip("| ")
        key = next((k for k in cells if re.search(k, what)), None)
        if key is not None and len(parts) >= 3:
            parts[1] = cells[key]
            line = " | ".join(parts)
        out.append(line)
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


TABLES: dict[str, Callable[[Context, list[str]], list[str]]] = {
    "presets": presets_table,
    "autonomous": autonomous_table,
    "sources": sources_table,
    "sweep-example": sweep_example_table,
    "speed": speed_table,
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
    parser.add_argument("--readme", type=Path, default=ROOT / "README.md")
    args = parser.parse_args(argv)
    names = [n.strip() for n in args.only.split(",") if n.strip()]
    unknown = [n for n in names if n not in TABLES]
    if unknown:
        parser.error(f"--only {','.join(unknown)}: allowed: {', '.join(TABLES)}")
    original = args.readme.read_text()
    text = original
    with tempfile.TemporaryDirectory() as scratch:
        ctx = Context(Path(scratch), args.tiny, args.all)
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

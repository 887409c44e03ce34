"""The results tables of the presets, from skymule's own functions (what the commands print).

Run: python benchmarks/bench_presets.py [--json benchmarks/results/presets.json]
(~1 min; SKYMULE_BENCH_TINY=1: the presets and autonomous tables only, a few seconds)

Tables (the pages that show them: docs/results.md, docs/missions.md, docs/channels.md,
docs/sweeps.md):

  presets        skymule compare {paper-sim-fixed, aadm-default} --policies greedy,hgad
  autonomous     skymule compare paper-sim-autonomous
  table-ii       skymule run paper-sim-autonomous with the paper's Table II buffers (x4)
  sources        skymule compare paper-sim-fixed --sources fspl,two-ray,al-hourani,3gpp-rma-av
  bounds         skymule compare {paper-sim-fixed, aadm-default} --policies ...,optimal-fixed
  planner        skymule compare paper-sim-autonomous --policies hgad,planner (3 variants)
  sweep-example  skymule sweep examples/sweep-paper.toml (1,000 missions; its wall time)

All but the last are deterministic: tests/test_readme_tables.py recomputes them and compares
them with the saved benchmarks/results/presets.json.
"""

from __future__ import annotations

import csv
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from _results import Table, json_option, table, write
from _sizes import tiny

ROOT = Path(__file__).resolve().parents[1]


def _compare(preset: str, policies: list[str], overrides: list[str] | None = None) -> Any:
    from skymule import compare_policies, load_scenario

    return compare_policies(load_scenario(preset, overrides or []), policies)


def presets() -> Table:
    """Greedy and HGAD on the fixed-path presets."""
    rows = []
    for preset in ("paper-sim-fixed", "aadm-default"):
        for r in _compare(preset, ["greedy", "hgad"]).rows():
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
    columns = ["preset", "policy", "downloaded [Mbit]", "completion", "handovers", "hover [s]"]
    return table([*columns, "distance [m]"], rows)


def autonomous() -> Table:
    """Greedy and HGAD on paper-sim-autonomous."""
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
        for r in _compare("paper-sim-autonomous", ["greedy", "hgad"]).rows()
    ]
    columns = ["policy", "downloaded [Mbit]", "completion", "hover [s]", "distance [m]"]
    return table([*columns, "energy [kJ]", "AADM score"], rows)


TABLE_II = (
    ((700, 500, 800, 1000), "LW4, LW3, LW1, LW2"),
    ((500, 800, 1000, 700), "LW3, LW2, LW4, LW1"),
    ((800, 500, 700, 1000), "LW4, LW1, LW3, LW2"),
    ((500, 1000, 700, 800), "LW2, LW4, LW3, LW1"),
)
"""The paper's Table II: buffers LW1..LW4 [Mbit] and HGAD's navigation order (published)."""


def table_ii() -> Table:
    """HGAD's visit order on paper-sim-autonomous for the paper's Table II buffers."""
    from skymule import load_scenario, simulate

    rows = []
    for buffers, paper in TABLE_II[:1] if tiny() else TABLE_II:
        sets = [f"sensors[{i}].buffer_mbit={b}" for i, b in enumerate(buffers)]
        order = simulate(load_scenario("paper-sim-autonomous", sets), "hgad").summary
        rows.append(["/".join(map(str, buffers)), paper, ", ".join(order["visit_order"])])
    return table(["buffers LW1..LW4 [Mbit]", "paper", "skymule"], rows, align="lll")


SOURCE_LABELS = {"al-hourani": "al-hourani (suburban)"}


def sources() -> Table:
    """Greedy and HGAD on paper-sim-fixed under four channel models."""
    from skymule import load_scenario
    from skymule.tasks.compare import compare_sources

    names = ["fspl", "two-ray", "al-hourani", "3gpp-rma-av"]
    found = compare_sources(load_scenario("paper-sim-fixed"), names, ["greedy", "hgad"])
    mbit = {(r["source"], r["policy"]): r["total_downloaded_mbit"] for r in found.rows()}
    rows = [
        [SOURCE_LABELS.get(s, s), f"{mbit[s, 'greedy']:.1f}", f"{mbit[s, 'hgad']:.1f}"]
        for s in names
    ]
    return table(["source", "greedy", "hgad"], rows)


def bounds() -> Table:
    """The bound and each policy's gap to it on the fixed presets."""
    rows = []
    for preset in ("paper-sim-fixed", "aadm-default"):
        found = _compare(preset, ["greedy", "hgad", "optimal-fixed"])
        upper = found.bounds[None].to_json_dict()
        cells = [
            preset,
            f"{upper['upper_bound_mbit']:.1f} ({upper['no_hover_upper_bound_mbit']:.1f})",
        ]
        for i, r in enumerate(found.rows()):
            gap = f"{100 * r['gap_to_bound_frac']:.2f}%"
            cells.append(f"{r['total_downloaded_mbit']:.1f} ({'gap ' if i == 0 else ''}{gap})")
        rows.append(cells)
    return table(["preset", "bound [Mbit] (no hover)", "greedy", "hgad", "optimal-fixed"], rows)


PLANNER_CASES: tuple[tuple[str, list[str]], ...] = (
    ("paper-sim-autonomous", []),
    ("same, 300 s", ["mission.duration_s=300"]),
    ("same, 1500 Mbit per tower", [f"sensors[{i}].buffer_mbit=1500" for i in range(4)]),
)


def planner() -> Table:
    """HGAD and the planner against the autonomous bound: as specified, shorter, larger."""
    rows = []
    for label, overrides in PLANNER_CASES:
        found = _compare("paper-sim-autonomous", ["hgad", "planner"], overrides)
        cells = [label]
        for r in found.rows():
            down = r["total_downloaded_mbit"]
            if r["aadm_complete"]:  # everything downloaded: when, and the score it earns
                done = f"done at {r['aadm_t1_s']:.0f} s, AADM {r['aadm_score']:.0f}"
                cells.append(f"{down:.1f} Mbit, {done}")
            else:
                cells.append(f"{down:.1f}")
        rows.append([*cells, f"{found.bounds[None].upper_bound_mbit:.1f}"])
    return table(["autonomous", "hgad", "planner", "bound"], rows)


def sweep_example() -> Table:
    """``skymule sweep examples/sweep-paper.toml``: its wall time (a fresh process, as a user
    runs it) and each policy's mean download."""
    with tempfile.TemporaryDirectory() as scratch:
        out = Path(scratch) / "sweep"
        command = [sys.executable, "-m", "skymule", "sweep", "examples/sweep-paper.toml"]
        start = time.perf_counter()
        subprocess.run([*command, "--out", str(out)], cwd=ROOT, check=True, capture_output=True)
        seconds = time.perf_counter() - start
        with (out / "summary.csv").open(newline="") as f:
            summary = {row["policy"]: row for row in csv.DictReader(f)}
    missions = sum(int(row["missions"]) for row in summary.values())
    cells = [
        f"{float(summary[p]['total_downloaded_mbit_mean']):.1f} ± "
        f"{float(summary[p]['total_downloaded_mbit_ci95']):.1f}"
        for p in ("greedy", "hgad")
    ]
    columns = ["missions", "wall time [s]", "greedy [Mbit] (mean ± 95% CI)", "hgad [Mbit]"]
    return table(columns, [[f"{missions:,}", f"{seconds:.1f}", *cells]])


TABLES: dict[str, Callable[[], Table]] = {
    "presets": presets,
    "autonomous": autonomous,
    "table-ii": table_ii,
    "sources": sources,
    "bounds": bounds,
    "planner": planner,
    "sweep-example": sweep_example,
}
DETERMINISTIC = ("presets", "autonomous", "table-ii", "sources", "bounds", "planner")
"""The tables without a timing: a fresh run gives the saved cells exactly."""


def main(path: Path | None) -> dict[str, Table]:
    """Compute every table (the first two in tiny mode), print them and save them to ``path``."""
    names = DETERMINISTIC[:2] if tiny() else list(TABLES)
    tables = {}
    for name in names:
        start = time.process_time()
        tables[name] = TABLES[name]()
        print(f"{name} ({time.process_time() - start:.1f} s CPU)")
        for row in tables[name]["rows"]:
            print("  " + " | ".join(row))
    write(path, tables)
    return tables


if __name__ == "__main__":
    main(json_option())

"""Every benchmark in benchmarks/ still runs, and writes the JSON the docs' tables come from.

The benchmarks are scripts a user runs by hand (docs/speed.md and the other pages show their
saved output), so nothing else imports them; this test runs each one as
``python benchmarks/bench_X.py --json PATH`` would (``__main__``), at its tiny size
(``SKYMULE_BENCH_TINY=1``), checks that it printed its figures and that ``PATH`` parses as the
format scripts/render_tables.py reads, with the same tables and columns as its saved output in
benchmarks/results/. No timing is asserted: the numbers of a tiny run are not measurements.
The trainers (``train_*.py``) run too, writing their models to the temporary folder and their
validation figures as a table.
"""

from __future__ import annotations

import json
import re
import runpy
import shutil
import sys
from pathlib import Path
from typing import Any

import pytest

#: Every benchmark script at its tiny size: in the default run, skipped by ``-m 'not slow'``.
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
RESULTS = BENCHMARKS / "results"
RENDER = runpy.run_path(str(ROOT / "scripts" / "render_tables.py"))

# what each script must print (a label of each figure it reports)
EXPECTED = {
    "bench_autonomous.py": ["greedy", "hgad", "Table II", "(True)", "one at a time"],
    "bench_bound.py": ["paper-sim-fixed: bound", "optimal-fixed", "bound 120 slots x 4 sensors"],
    "bench_channel.py": ["fspl", "fspl + shadowing", "radio map: query", "dense reference"],
    "bench_compilers.py": ["numba (skymule compiled loop)", "mission-slots/CPU-s"],
    "bench_engine.py": ["single (1 missions)", "numpy + summaries", "memory bandwidth"],
    "bench_envs.py": ["vector env", "single envs", "ratio"],
    "bench_vector_env.py": ["single envs stepped in a loop", "numpy paths", "ratio to single"],
    "bench_fleet.py": ["coordinated", "bound", "coordinated - independent hgad"],
    "bench_invariants.py": ["missions with faults run", "y = min(R dt, Q)", "speed cap"],
    "bench_policies.py": ["serve sensor 0", "largest first", "totals equal: True", "beyond act"],
    "bench_planner.py": ["planner gain over hgad", "mean gap to bound", "above the bound: 0"],
    "bench_presets.py": ["presets", "paper-sim-fixed | hgad", "autonomous"],
    "bench_resilience.py": ["robust - plain", "hgad-robust", "planner-robust", "ended home"],
    "bench_single.py": ["paper-sim-fixed", "aadm-default", "slots/s"],
    "bench_sim2real.py": ["neural + DT prior", "noise floor", "fit time", "twin (DT map)"],
    "bench_startup.py": ["--help", "run", "x --help in wall time", "CPU"],
    "bench_suite.py": ["tests:", "passed", "s wall"],
    "bench_sweep.py": ["sample-10k", "us CPU/mission", "process executor", "seed axis"],
    "train_ppo.py": ["hgad", "bound", "PPO - HGAD"],
    "bench_learned.py": [
        "learned vs hgad",
        "row: condition=faults",
        "recorded: twin=dt_flight.csv policy=learned",
        "inference, one mission",
    ],
    "train_learned.py": ["es: 2 generations", "validation of the kept model", "learning curve"],
}

NEEDS = {"train_ppo.py": "stable_baselines3"}
"""Scripts of an optional extra (``skymule[rl]``): skipped where it is not installed."""

SAVED = {
    "bench_autonomous.py": "autonomous.json",
    "bench_bound.py": "bound.json",
    "bench_channel.py": "channel.json",
    "bench_engine.py": "engine.json",
    "bench_learned.py": "learned.json",
    "bench_policies.py": "policies.json",
    "bench_presets.py": "presets.json",
    "bench_sim2real.py": "sim2real.json",
    "bench_startup.py": "startup.json",
    "bench_suite.py": "suite.json",
    "bench_sweep.py": "sweep.json",
}
"""Benchmark -> its saved output in benchmarks/results/, whose tables the pages show."""

JSON_PENDING: dict[str, str] = {}
"""Benchmarks whose ``--json`` another change adds: run here without it."""


def scripts() -> list[str]:
    found = [*BENCHMARKS.glob("bench_*.py"), *BENCHMARKS.glob("train_*.py")]
    return sorted(p.name for p in found)


def run_script(name: str, args: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """``python benchmarks/NAME ARGS`` in this process, at the tiny size."""
    monkeypatch.setenv("SKYMULE_BENCH_TINY", "1")
    monkeypatch.syspath_prepend(str(BENCHMARKS))  # as `python benchmarks/X.py` has it
    monkeypatch.setattr(sys, "argv", [str(BENCHMARKS / name), *args])
    runpy.run_path(str(BENCHMARKS / name), run_name="__main__")


def written_tables(path: Path, saved: str | None) -> dict[str, dict[str, Any]]:
    """The tables of ``path``, checked against the renderer's format and the saved file."""
    tables: dict[str, dict[str, Any]] = RENDER["load_tables"](path.parent)
    assert tables and all(t["rows"] for t in tables.values()), tables
    for table in tables.values():  # every table renders
        RENDER["markdown"](table["columns"], table["rows"], table.get("align"))
    if saved is not None:
        before = json.loads((RESULTS / saved).read_text())["tables"]
        shown = set(tables) & set(before)
        assert shown, f"writes {sorted(tables)}, none of the saved {sorted(before)}"
        for name in shown:
            assert tables[name]["columns"] == before[name]["columns"], name
    return tables


def test_every_script_is_smoke_tested_and_every_saved_file_has_its_benchmark() -> None:
    assert scripts() == sorted(EXPECTED)
    produced = {*SAVED.values(), "planner.json", "sweep-scale.json"}
    assert sorted(p.name for p in RESULTS.glob("*.json")) == sorted(produced)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_benchmark_runs_at_tiny_size_and_writes_its_tables(
    name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    if name in NEEDS:
        pytest.importorskip(NEEDS[name])
    out = tmp_path / "out" / "tables.json"
    writes_json = name not in JSON_PENDING
    run_script(name, ["--json", str(out)] if writes_json else [], monkeypatch)
    printed = capsys.readouterr().out
    for label in EXPECTED[name]:
        assert label in printed, f"{name} no longer prints {label!r}:\n{printed}"
    assert re.search(r"\d+\.\d+", printed), f"{name} printed no figures:\n{printed}"
    assert not re.search(r"\bnan\b", printed, flags=re.I), f"{name} printed NaN:\n{printed}"
    if writes_json:
        tables = written_tables(out, SAVED.get(name))
        if name == "bench_sim2real.py":  # the extrapolating split and the reference rows
            rows = tables["sim2real"]["rows"]
            assert {"region (east 60%)", "time (last 60%)"} <= {row[1] for row in rows}
            assert {"ref: free space", "ref: oracle refit", "neural + DT prior"} <= {
                row[0] for row in rows
            }


@pytest.mark.slow
def test_the_planner_speed_mode_writes_its_speed_row(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``bench_planner.py --speed N --before REV`` (the speed table's planner row)."""
    out = tmp_path / "out" / "planner.json"
    run_script(
        "bench_planner.py", ["--speed", "2", "--before", "HEAD", "--json", str(out)], monkeypatch
    )
    tables = written_tables(out, "planner.json")
    assert "identical plans in 2 of 2 missions" in tables["speed-planner"]["rows"][0][1]


@pytest.mark.slow
def test_the_sweep_scale_mode_adds_its_rows_to_the_saved_table(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``bench_sweep.py --missions N --report --json FILE`` (the 10-million-mission benchmark
    at a tiny size): its rows join the ones FILE holds, by size and executor."""
    out = tmp_path / "out" / "sweep-scale.json"
    out.parent.mkdir()
    shutil.copy(RESULTS / "sweep-scale.json", out)
    args = ["--missions", "40", "--executors", "inprocess", "--report", "--json", str(out)]
    run_script("bench_sweep.py", args, monkeypatch)
    rows = written_tables(out, "sweep-scale.json")["sweep-scale"]["rows"]
    before = json.loads((RESULTS / "sweep-scale.json").read_text())["tables"]["sweep-scale"]
    assert [r[:2] for r in rows[:2]] == [["40", "inprocess"], ["40", "`skymule report` of it"]]
    assert rows[2:] == before["rows"]

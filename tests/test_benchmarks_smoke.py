"""Every benchmark in benchmarks/ still runs: each at its tiny size, in this process.

The benchmarks are scripts a user runs by hand (the README's Speed table quotes them), so
nothing else imports them; this test runs each one as ``python benchmarks/bench_X.py`` would
(``__main__``), with ``SKYMULE_BENCH_TINY=1``, and checks that it printed its figures. No
timing is asserted: the numbers of a tiny run are not measurements.
"""

from __future__ import annotations

import json
import re
import runpy
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
README_TABLES = runpy.run_path(str(ROOT / "scripts" / "update_readme_tables.py"))

# what each benchmark must print (a label of each figure it reports)
EXPECTED = {
    "bench_autonomous.py": ["greedy", "hgad", "Table II", "(True)", "one at a time"],
    "bench_bound.py": ["paper-sim-fixed: bound", "optimal-fixed", "bound 120 slots x 4 sensors"],
    "bench_channel.py": ["fspl", "fspl + shadowing", "radio map: query", "dense reference"],
    "bench_compilers.py": ["numba (skymule compiled loop)", "mission-slots/CPU-s"],
    "bench_engine.py": ["single (2 missions)", "numpy + summaries", "memory bandwidth"],
    "bench_envs.py": ["vector env", "single envs", "ratio"],
    "bench_vector_env.py": ["single envs stepped in a loop", "numpy paths", "ratio to single"],
    "bench_fleet.py": ["coordinated", "bound", "coordinated - independent hgad"],
    "bench_invariants.py": ["missions with faults run", "y = min(R dt, Q)", "speed cap"],
    "bench_policies.py": ["serve sensor 0", "largest first", "totals equal: True", "beyond act"],
    "bench_planner.py": ["planner gain over hgad", "mean gap to bound", "above the bound: 0"],
    "bench_resilience.py": ["robust - plain", "hgad-robust", "planner-robust", "ended home"],
    "bench_single.py": ["paper-sim-fixed", "aadm-default", "slots/s"],
    "bench_sim2real.py": ["neural + DT prior", "noise floor", "fit time", "twin (DT map)"],
    "bench_startup.py": ["--help", "run", "x --help in wall time", "CPU"],
    "bench_sweep.py": ["sample-10k", "us CPU/mission", "process executor", "seed axis"],
    "train_ppo.py": ["hgad", "bound", "PPO - HGAD"],
    "bench_learned.py": ["learned vs hgad", "row: condition=faults", "inference, one mission"],
    "train_learned.py": ["es: 2 generations", "validation of the kept model", "learning curve"],
}

NEEDS = {"train_ppo.py": "stable_baselines3"}
"""Benchmarks of an optional extra (``skymule[rl]``): skipped where it is not installed."""

NOT_PARSED_HERE = {"bench_planner.py": "its README row comes from --speed N, not the default run"}
"""Benchmarks whose README speed cells this test does not parse from the default tiny run."""


def test_every_benchmark_is_smoke_tested() -> None:
    scripts = [*BENCHMARKS.glob("bench_*.py"), *BENCHMARKS.glob("train_*.py")]
    assert sorted(p.name for p in scripts) == sorted(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_benchmark_runs_at_tiny_size(
    name: str,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
) -> None:
    if name in NEEDS:
        pytest.importorskip(NEEDS[name])
    monkeypatch.setenv("SKYMULE_BENCH_TINY", "1")
    monkeypatch.syspath_prepend(str(BENCHMARKS))  # as `python benchmarks/X.py` has it
    table = tmp_path / "table.json"
    extra = ["--json", str(table)] if name == "bench_sim2real.py" else []
    monkeypatch.setattr(sys, "argv", [str(BENCHMARKS / name), *extra])
    runpy.run_path(str(BENCHMARKS / name), run_name="__main__")
    out = capsys.readouterr().out
    for label in EXPECTED[name]:
        assert label in out, f"{name} no longer prints {label!r}:\n{out}"
    assert re.search(r"\d+\.\d+", out), f"{name} printed no figures:\n{out}"
    assert not re.search(r"\bnan\b", out, flags=re.I), f"{name} printed NaN:\n{out}"
    if name in README_TABLES["SPEED_BENCHES"] and name not in NOT_PARSED_HERE:
        # the README's speed cells are parsed from this output: the parser must still fit it
        _, parse = README_TABLES["SPEED_BENCHES"][name]
        cells = parse(out)
        assert cells and all(cells.values()), f"{name}: README speed cells {cells}"
    if name == "bench_sim2real.py":  # its README table is parsed from this output
        rows = README_TABLES["sim2real_rows"](out)
        labels = [r[0] for r in rows]
        assert labels[0] == "twin (DT map)", labels
        assert {"neural + DT prior", "ref: free space", "ref: oracle refit"} <= set(labels)
        # --json: the table the README renderer reads, the extrapolating split included
        written = json.loads(table.read_text())["tables"]["sim2real"]
        assert written["columns"][:3] == ["map", "held out", "SNR RMSE [dB]"] and written["note"]
        assert all(len(row) == len(written["columns"]) for row in written["rows"])
        splits = {row[1] for row in written["rows"]}
        assert {"region (east 60%)", "time (last 60%)"} <= splits


def test_the_sweep_scale_mode_runs_and_fills_the_readme_rows(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``bench_sweep.py --missions N --report`` (the 10-million-mission benchmark at a tiny
    size): wall, CPU and peak RSS per executor and the report's, parsed into the README's
    sweep-scale rows."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    script = str(BENCHMARKS / "bench_sweep.py")
    monkeypatch.setattr(
        sys, "argv", [script, "--missions", "40", "--executors", "inprocess", "--report"]
    )
    runpy.run_path(script, run_name="__main__")
    rows = README_TABLES["scale_rows"](capsys.readouterr().out)
    assert set(rows) == {("40", "inprocess"), ("40", "`skymule report` of it")}
    assert all(cell for cell in rows["40", "inprocess"])

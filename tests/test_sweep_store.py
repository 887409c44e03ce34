"""Sweep folders under stress: locks, damaged parts, other sweep files, huge plans, dead parents."""

from __future__ import annotations

import itertools
import json
import os
import signal
import socket
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import pandas as pd
import psutil
import pytest

from conftest import SMALL_SWEEP, run_cli, write
from skymule.experiments import store
from skymule.experiments.run import auto_chunk_size, run_sweep
from skymule.experiments.sweep import load_sweep, plan_missions
from skymule.scenario import load_scenario, scenario_from_dict
from skymule.tasks.simulate import simulate

SMALL = SMALL_SWEEP


def test_a_second_sweep_on_a_locked_folder_names_the_holder_and_exits_2(tmp_path):
    path = write(tmp_path, SMALL.format(n=2))
    out = tmp_path / "out"
    with store.locked(out):
        result = run_cli("sweep", path, "--out", out, "--executor", "inprocess", "--quiet")
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert f"pid {os.getpid()}" in lines[0] and socket.gethostname() in lines[0]
    assert not (out / "results").exists()
    # released: the same sweep now runs
    assert (
        run_cli("sweep", path, "--out", out, "--executor", "inprocess", "--quiet").returncode == 0
    )
    assert not (out / store.HOLDER).exists()


def test_a_lock_dies_with_its_process(tmp_path):
    """A sweep killed while it holds the folder leaves no lock behind (the OS releases it),
    only its holder note, which the next sweep replaces."""
    out = tmp_path / "out"
    code = (
        "import sys, time\n"
        "from pathlib import Path\n"
        "from skymule.experiments import store\n"
        "with store.locked(Path(sys.argv[1])):\n"
        "    print('held', flush=True)\n"
        "    time.sleep(600)\n"
    )
    holder = subprocess.Popen([sys.executable, "-c", code, str(out)], stdout=subprocess.PIPE)
    try:
        assert holder.stdout is not None and holder.stdout.readline() == b"held\n"
        with pytest.raises(store.SkymuleError, match=f"pid {holder.pid}"), store.locked(out):
            pass
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
    assert (out / store.HOLDER).exists()  # killed: its note stays, its lock does not
    spec = load_sweep(write(tmp_path, SMALL.format(n=2)))
    outcome = run_sweep(spec, out, executor="inprocess", progress=False)
    assert outcome.n_run == len(spec) == 8
    assert not (out / store.HOLDER).exists()


def test_a_part_a_killed_worker_was_writing_is_removed_and_run_again(tmp_path):
    # Ctrl-C ends a process pool's workers with SIGTERM (no clean-up runs), so the part a
    # worker was writing stays under its temporary name until the sweep is resumed
    spec = load_sweep(write(tmp_path, SMALL.format(n=2)))
    out = tmp_path / "out"
    (out / store.PARTS).mkdir(parents=True)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)  # fmt: skip
    stale = out / store.PARTS / f".part-000000.parquet.{dead.stdout.strip()}.0123456789ab.tmp"
    stale.write_bytes(b"half a part")
    mine = out / store.PARTS / f".part-000004.parquet.{os.getpid()}.0123456789ab.tmp"
    mine.write_bytes(b"a live writer's")
    outcome = run_sweep(spec, out, executor="inprocess", progress=False)
    assert outcome.n_run == len(spec) == 8
    assert not stale.exists() and mine.exists()  # a live writer's file is not touched


def test_a_damaged_part_is_named_set_aside_and_its_missions_run_again(tmp_path, capsys):
    spec = load_sweep(write(tmp_path, SMALL.format(n=5)))  # 20 missions
    out = tmp_path / "out"
    first = run_sweep(spec, out, executor="inprocess", chunk_size=6, progress=False)
    parts = store.part_paths(out)
    assert len(parts) == 4
    victim = parts[1]
    lost = pd.read_parquet(victim)["mission_id"].tolist()
    victim.write_bytes(b"not parquet at all" * 10)
    again = run_sweep(spec, out, executor="inprocess", chunk_size=6, progress=False)
    warning = capsys.readouterr().err
    assert str(victim) in warning and "run again" in warning
    assert again.n_run == len(lost)
    assert again.results["mission_id"].tolist() == first.results["mission_id"].tolist()
    pd.testing.assert_frame_equal(again.results, first.results)
    assert victim.with_name(victim.name + ".damaged").exists()
    stored = pd.concat(pd.read_parquet(p) for p in store.part_paths(out))
    assert stored["mission_id"].is_unique and len(stored) == 20  # nothing lost, nothing twice


def test_a_folder_refuses_another_sweep_file(tmp_path):
    out = tmp_path / "out"
    first = write(tmp_path, SMALL.format(n=2), "a.toml")
    other = write(tmp_path, SMALL.format(n=3), "b.toml")
    assert (
        run_cli("sweep", first, "--out", out, "--executor", "inprocess", "--quiet").returncode == 0
    )
    result = run_cli("sweep", other, "--out", out, "--executor", "inprocess", "--quiet")
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(first) in lines[0] and str(other) in lines[0], result.stderr
    # the same file again resumes (nothing to run)
    again = run_cli("sweep", first, "--out", out, "--executor", "inprocess", "--quiet")
    assert again.returncode == 0 and "ran 0 of 8" in " ".join(again.stdout.split())


def test_a_folder_from_the_previous_id_scheme_is_refused_clearly(tmp_path):
    out = tmp_path / "out"
    (out / store.PARTS).mkdir(parents=True)
    pd.DataFrame({"mission_index": [0], "mission_id": ["0123456789abcdef"]}).to_parquet(
        out / store.PARTS / "part-00000.parquet"
    )
    path = write(tmp_path, SMALL.format(n=2))
    result = run_cli("sweep", path, "--out", out, "--executor", "inprocess", "--quiet")
    assert result.returncode == 2
    assert "older skymule" in result.stderr and "new --out" in result.stderr


def test_a_billion_seeds_are_planned_lazily(tmp_path):
    text = SMALL.format(n=10**9)
    tracemalloc.start()
    try:
        spec = load_sweep(write(tmp_path, text))
        first = list(itertools.islice(plan_missions(spec), 1000))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(spec) == 2 * 10**9 * 2
    assert [m.index for m in first] == list(range(1000))
    assert len({m.mission_id for m in first}) == 1000
    assert peak < 50 * 2**20, f"planning allocated {peak / 2**20:.0f} MiB"


def test_missions_sharing_a_track_across_seeds_keep_their_own_shadowing(tmp_path):
    """With shadowing the seed changes the track: rows equal single runs, seed by seed."""
    text = SMALL.format(n=2).replace(
        '"mission.duration_s" = [120, 200]', '"radio.shadowing_std_db" = [6.0]'
    )
    spec = load_sweep(write(tmp_path, text))
    outcome = run_sweep(spec, tmp_path / "out", executor="inprocess", progress=False)
    for row in outcome.results.to_dict("records"):
        data = json.loads(json.dumps(load_scenario("paper-sim-fixed").to_toml_dict()))
        data["seed"] = row["seed"]
        data["policy"]["name"] = row["policy.name"]
        data["radio"]["shadowing_std_db"] = 6.0
        for i, sensor in enumerate(data["sensors"]):
            sensor["buffer_mbit"] = row[f"sensors[{i}].buffer_mbit"]
        summary = simulate(scenario_from_dict(data, "t", Path("."))).summary
        assert row["total_downloaded_mbit"] == pytest.approx(
            summary["total_downloaded_mbit"], rel=1e-12
        )
    by_seed = outcome.results.groupby("seed")["total_downloaded_mbit"].apply(tuple)
    assert by_seed.nunique() == 2  # the two seeds' fields differ


def test_chunk_size_follows_the_memory_budget(tmp_path):
    spec = load_sweep(write(tmp_path, SMALL.format(n=500)))  # 2,000 missions
    assert auto_chunk_size(spec, 500, 1) == 500
    assert auto_chunk_size(spec, 500, 4) == 250  # two chunks per worker at least
    small_budget = auto_chunk_size(spec, 500, 1, budget_bytes=2**20)
    assert 1 <= small_budget < 500
    long = write(tmp_path, SMALL.format(n=500).replace("[120, 200]", "[3600]"), "long.toml")
    assert auto_chunk_size(load_sweep(long), 500, 1, budget_bytes=2**20) < small_budget


WATCHED = """
import os, sys, time
from skymule.experiments.executors import open_executor

def pid(_):
    time.sleep(0.5)
    return os.getpid()

if __name__ == "__main__":
    with open_executor("process", 2) as pool:
        pids = sorted(set(pool.map(pid, range(8))))
        print(" ".join(map(str, pids)), flush=True)
        time.sleep(600)
"""


def _gone(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


def test_process_workers_exit_when_the_sweep_process_is_killed(tmp_path):
    script = write(tmp_path, WATCHED, "watched.py")
    parent = subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, text=True, env=dict(os.environ)
    )
    workers: list[int] = []
    try:
        assert parent.stdout is not None
        workers = [int(p) for p in parent.stdout.readline().split()]  # waits for start-up
        assert workers and all(not _gone(p) for p in workers)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 60
        while not all(_gone(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert all(_gone(p) for p in workers), "workers outlived their parent"
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        if parent.stdout is not None:
            parent.stdout.close()
        for pid in workers:
            if not _gone(pid):
                os.kill(pid, signal.SIGKILL)


@pytest.mark.parametrize("axis", ['"mission.duration_s" = [120, 120]', "seed = [4, 4]"])
def test_a_value_listed_twice_is_one_line_and_exit_2(tmp_path, axis):
    path = write(tmp_path, f'base = "paper-sim-fixed"\n[axes]\npolicy.name = ["greedy"]\n{axis}\n')
    result = run_cli("sweep", path, "--out", tmp_path / "out", "--executor", "inprocess")
    assert result.returncode == 2
    assert "twice" in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_the_run_order_groups_policies_and_plans_the_same_missions(tmp_path):
    """Sweeps run paired axes innermost (shared tracks in one chunk): same missions, same ids."""
    spec = load_sweep(write(tmp_path, SMALL.format(n=2)))  # policy x seed x duration = 8
    in_order = list(plan_missions(spec))
    grouped = list(plan_missions(spec, paired_last=True))
    assert [m.index for m in in_order] == list(range(8))
    assert [m.index for m in grouped[:4]] == [0, 4, 1, 5]
    assert [m.values[0] for m in grouped[:2]] == ["greedy", "hgad"]
    assert grouped[0].values[1:] == grouped[1].values[1:]  # same seed, draws and duration
    assert sorted(grouped, key=lambda m: m.index) == in_order

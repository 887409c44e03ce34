"""Sweeps at scale: plan ranges, the streamed merge of parts, summaries batch by batch,
byte-identical files across executors, chunkings and resumes, and a Dask cluster reached
through its scheduler address."""

from __future__ import annotations

import random
import shutil
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pytest

from conftest import SMALL_SWEEP, run_cli, write
from skymule.experiments import store
from skymule.experiments.run import run_sweep
from skymule.experiments.sweep import load_sweep, plan_missions, sweep_plan

#: Sweeps across processes and a Dask cluster: in the default run, skipped by ``-m 'not slow'``.
pytestmark = pytest.mark.slow

PRODUCT = """
base = "paper-sim-fixed"
seed = 3
[axes]
"mission.duration_s" = [120, 200, 300]
policy.name = ["greedy", "hgad"]
seed = { range = [0, 4] }
"sensors[*].buffer_mbit" = { dist = "uniform", low = 50, high = 600 }
policy.params.max_hover_s = [10, 20]
"""


@pytest.mark.parametrize("sample", [False, True])
def test_any_range_of_the_plan_is_that_slice_of_the_whole(tmp_path: Path, sample: bool) -> None:
    text = PRODUCT.replace('policy.name = ["greedy", "hgad"]', 'policy.name = ["hgad"]')
    if sample:
        text = text.replace("seed = 3", "seed = 3\nmode = { sample = 7 }")
    spec = load_sweep(write(tmp_path, text))
    plan = sweep_plan(spec)
    whole = list(plan.missions())
    assert whole == list(plan_missions(spec, paired_last=True))
    assert sorted(m.index for m in whole) == list(range(len(spec)))
    rng = random.Random(0)
    for _ in range(60):
        start = rng.randrange(len(plan))
        stop = rng.randrange(start, len(plan) + 3)
        assert list(plan.missions(start, stop)) == whole[start:stop]
        assert plan.indices(start, stop).tolist() == [m.index for m in whole[start:stop]]


def _frame(indices: list[int], policy: list[str], value: list[float]) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "mission_index": indices,
            "mission_id": [f"m{i}" for i in indices],
            "policy": policy,
            "total_downloaded_mbit": value,
        }
    )


def test_the_merge_orders_dedupes_and_conforms_parts_across_buckets(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Parts holding far-apart missions (a policy axis first), a mission stored twice (an
    orphaned worker) and a part without a column: results.parquet has each mission once, in
    order, in row groups of BUCKET_ROWS, and the summary equals numpy's on the same values."""
    monkeypatch.setattr(store, "BUCKET_ROWS", 4)
    out = tmp_path / "out"
    rng = np.random.default_rng(1)
    values = rng.uniform(0, 100, 20)
    policies = ["greedy" if i < 10 else "hgad" for i in range(20)]
    for first in range(0, 10, 3):  # missions i and i + 10 in one part
        chosen = [i for i in range(first, min(first + 3, 10))]
        both = chosen + [i + 10 for i in chosen]
        frame = _frame(both, [policies[i] for i in both], [values[i] for i in both])
        frame["completion"] = frame["total_downloaded_mbit"] / 100
        store.write_part(out, frame)
    store.write_part(out, _frame([4], ["greedy"], [values[4]]))  # stored twice, no completion
    merged = store.consolidate(out)
    table = pa.parquet.ParquetFile(out / store.RESULTS)
    assert merged.rows == 20 and table.metadata.num_row_groups == 5
    results = pd.read_parquet(out / store.RESULTS)
    assert results["mission_index"].tolist() == list(range(20))
    assert results["total_downloaded_mbit"].tolist() == values.tolist()
    assert results["completion"].notna().all()
    want = store.summary_table(results)  # the same statistics in one batch
    for metric in ("total_downloaded_mbit", "completion"):
        for policy, group in results.groupby("policy"):
            row = merged.summary.set_index("policy").loc[policy]
            sample = group[metric].to_numpy()
            assert row[f"{metric}_mean"] == pytest.approx(sample.mean(), rel=1e-12)
            assert row[f"{metric}_ci95"] == pytest.approx(store.ci95_half_width(sample), rel=1e-9)
    pd.testing.assert_frame_equal(merged.summary, want, rtol=1e-12)


def test_batched_summary_statistics_match_numpy_with_nan_and_inf() -> None:
    rng = np.random.default_rng(7)
    values = rng.normal(5e3, 2.0, 1000)
    values[[3, 500]] = np.nan
    frame = pd.DataFrame({"policy": ["a"] * 1000, "total_downloaded_mbit": values})
    frame["distance_m"] = 4962.889544679233  # equal values: mean exact, CI exactly 0
    frame["completion"] = values
    frame.loc[7, "completion"] = np.inf
    stats = store.SummaryStats()
    for start in range(0, 1000, 137):
        stats.add(pa.Table.from_pandas(frame.iloc[start : start + 137], preserve_index=False))
    row = stats.table().iloc[0]
    assert row["missions"] == 1000
    assert row["total_downloaded_mbit_mean"] == pytest.approx(np.nanmean(values), rel=1e-14)
    assert row["total_downloaded_mbit_ci95"] == pytest.approx(
        store.ci95_half_width(values), rel=1e-9
    )
    assert row["distance_m_mean"] == 4962.889544679233 and row["distance_m_ci95"] == 0.0
    assert row["completion_mean"] == np.inf  # as numpy.nanmean


def test_batched_summary_groups_by_policy_and_level_as_pandas_does() -> None:
    """One row per policy and value of each level column (a missing value a group of its
    own, last), in pandas' groupby order, whatever the batches; each group's statistics as
    numpy's on its values."""
    rng = np.random.default_rng(3)
    n = 600
    frame = pd.DataFrame(
        {
            "policy": rng.choice(["hgad", "greedy"], n),
            "mission.duration_s": rng.choice([300, 120, 200], n),
            "policy.params.min_rate_mbps": rng.choice([6.0, 0.0, np.nan], n),
            "total_downloaded_mbit": rng.uniform(0, 500, n),
        }
    )
    levels = ["mission.duration_s", "policy.params.min_rate_mbps", "not.a.column"]
    stats = store.SummaryStats(levels)
    for start in range(0, n, 97):
        stats.add(pa.Table.from_pandas(frame.iloc[start : start + 97], preserve_index=False))
    got = stats.table()
    keys = ["policy", "mission.duration_s", "policy.params.min_rate_mbps"]
    assert list(got.columns[:4]) == [*keys, "missions"]
    groups = frame.groupby(keys, sort=True, dropna=False)["total_downloaded_mbit"]
    assert len(got) == groups.ngroups == 2 * 3 * 3
    for (_, row), (key, values) in zip(got.iterrows(), groups, strict=True):
        assert row["policy"] == key[0] and row["mission.duration_s"] == key[1]
        assert row["policy.params.min_rate_mbps"] == key[2] or np.isnan(key[2])
        assert np.isnan(key[2]) == np.isnan(row["policy.params.min_rate_mbps"])
        assert row["missions"] == values.size
        assert row["total_downloaded_mbit_mean"] == pytest.approx(values.mean(), rel=1e-12)
        assert row["total_downloaded_mbit_ci95"] == pytest.approx(
            store.ci95_half_width(values.to_numpy()), rel=1e-9
        )
    # the rows as one batch: the same table
    pd.testing.assert_frame_equal(store.summary_table(frame, levels), got, rtol=1e-12)


def _files(folder: Path) -> tuple[bytes, bytes]:
    return (folder / store.RESULTS).read_bytes(), (folder / store.SUMMARY).read_bytes()


def test_files_are_byte_identical_across_chunkings_executors_and_a_resume(
    tmp_path: Path,
) -> None:
    spec = load_sweep(write(tmp_path, SMALL_SWEEP.format(n=6)))  # 24 missions
    one = tmp_path / "one"
    run_sweep(spec, one, executor="inprocess", chunk_size=500, progress=False)
    other = tmp_path / "other"
    run_sweep(spec, other, executor="process", workers=2, chunk_size=5, progress=False)
    assert _files(one) == _files(other)
    # a resume: half the parts lost, the rest run again with another chunk size
    for part in store.part_paths(other)[::2]:
        part.unlink()
    (other / store.RESULTS).unlink()
    again = run_sweep(spec, other, executor="inprocess", chunk_size=7, progress=False)
    assert 0 < again.n_run < 24 and again.n_missions == 24
    assert _files(one) == _files(other)


@pytest.fixture
def cluster() -> Iterator[str]:
    """A Dask cluster of separate worker processes on this machine, by its scheduler address
    (any free port); always closed."""
    distributed = pytest.importorskip("distributed", reason="needs the dask extra")
    import dask

    from skymule.experiments.executors import DASK_START_TIMEOUT_S, QUIET_DASK

    with dask.config.set(
        {"distributed.comm.timeouts.connect": f"{DASK_START_TIMEOUT_S}s", **QUIET_DASK}
    ):
        local = distributed.LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            scheduler_port=0,
            dashboard_address=None,
        )
    try:
        yield str(local.scheduler_address)
    finally:
        local.close(timeout=60)


POLICY = '''
import numpy as np

class FirstWithData:
    """Serve the first sensor that holds data (a plug-in the workers cannot import)."""

    name = "first-with-data"

    def reset(self, context):
        pass

    def act(self, observation):
        from skymule.policies.base import Action

        holding = np.flatnonzero((observation.remaining_bit > 0) & (observation.rate_bps > 0))
        return Action(serve=int(holding[0]) if holding.size else None)
'''


@pytest.mark.filterwarnings("ignore::ResourceWarning")
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_a_sweep_on_a_cluster_through_its_scheduler_address(
    cluster: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--scheduler`` reaches an existing cluster: its workers plan their ranges, send their
    parts back as bytes and import a ``module:Class`` policy uploaded from here; the files
    equal an in-process run's byte for byte."""
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    (plugins / "firstpolicy.py").write_text(POLICY)
    monkeypatch.chdir(plugins)  # found here by the sweep process, not by the workers
    text = SMALL_SWEEP.format(n=2).replace(
        'policy.name = ["greedy", "hgad"]', 'policy.name = ["greedy", "firstpolicy:FirstWithData"]'
    )
    spec = load_sweep(write(tmp_path, text))
    here = run_sweep(spec, tmp_path / "here", executor="inprocess", progress=False)
    there = run_sweep(
        spec, tmp_path / "there", executor="dask", scheduler=cluster, chunk_size=3, progress=False
    )
    assert here.n_missions == there.n_run == 8
    assert set(here.results["policy.name"]) == {"greedy", "firstpolicy:FirstWithData"}
    assert _files(tmp_path / "here") == _files(tmp_path / "there")


def test_dask_without_a_scheduler_or_an_unreachable_one_is_one_line(tmp_path: Path) -> None:
    path = write(tmp_path, SMALL_SWEEP.format(n=1))
    done = run_cli("sweep", path, "--out", tmp_path / "a", "--executor", "dask")
    assert done.returncode == 2 and "--scheduler tcp://HOST:PORT" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    if "distributed" not in sys.modules:
        pytest.importorskip("distributed", reason="connecting needs the dask extra")
    done = run_cli(
        "sweep", path, "--out", tmp_path / "b", "--scheduler", "tcp://127.0.0.1:9", "--quiet"
    )
    assert done.returncode == 2 and "cannot connect" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    shutil.rmtree(tmp_path / "b", ignore_errors=True)

"""skymule report SWEEPDIR: sweep report from results.parquet + summary.csv only."""

from __future__ import annotations

import base64
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from conftest import run_cli
from skymule.experiments.run import run_sweep
from skymule.experiments.sweep import load_sweep

SWEEP = """
base = "paper-sim-fixed"
seed = 5
[axes]
policy.name = ["greedy", "hgad"]
seed = { range = [0, 8] }
"sensors[*].buffer_mbit" = { dist = "uniform", low = 50, high = 600 }
"mission.duration_s" = [100, 160]
"""
SECTIONS = ("summary", "distributions", "paired", "parameters")
FIGURES = ("sweep-download", "sweep-completion", "sweep-gain", "sweep-parameter-1")


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A sweep folder made in-process, then moved: the report needs only its files."""
    work = tmp_path_factory.mktemp("made")
    (work / "sweep.toml").write_text(SWEEP)
    run_sweep(load_sweep(work / "sweep.toml"), work / "sw", executor="inprocess", progress=False)
    moved = tmp_path_factory.mktemp("copied") / "sw"
    shutil.copytree(work / "sw", moved)
    shutil.rmtree(work)
    done = run_cli("report", moved)
    assert done.returncode == 0, done.stderr
    return moved


def page(folder: Path) -> str:
    return (folder / "report.html").read_text(encoding="utf-8")


def gain_rows(text: str) -> dict[str, dict[str, str]]:
    rows = re.findall(r'<tr class="gain" ([^>]*)>(.*?)</tr>', text)
    out = {}
    for attrs, cells in rows:
        data = dict(re.findall(r'data-([\w-]+)="([^"]*)"', attrs))
        data["cells"] = "|".join(re.findall(r"<td>(.*?)</td>", cells))
        out[data["policy"]] = data
    return out


def test_every_section_and_figure_embedded_offline(sweep_dir: Path) -> None:
    text = page(sweep_dir)
    for section in SECTIONS:
        assert f'<section id="{section}">' in text
    for key in FIGURES:
        block = re.search(
            rf'data-fig="{key}"><img alt="[^"]*" src="data:image/png;base64,([^"]+)"', text
        )
        assert block, key
        assert base64.b64decode(block.group(1))[:8] == b"\x89PNG\r\n\x1a\n"
        assert (sweep_dir / "figures" / f"{key}.png").is_file()
        assert (sweep_dir / "figures" / f"{key}.pdf").read_bytes()[:5] == b"%PDF-"
    # mission.duration_s is the one discrete axis; the buffers sum is the drawn one; both are
    # named in words with units (issue 13), not by their scenario keys
    assert "vs mission duration [s]" in text and "vs total buffer [Mbit]" in text
    assert "sensors[*]" not in text.split('id="parameter-table"')[0]
    assert not re.search(r"https?://", text)
    assert not re.search(r'(src|href)="(?!data:|#)', text)


def test_summary_table_is_summary_csv(sweep_dir: Path) -> None:
    summary = pd.read_csv(sweep_dir / "summary.csv")
    table = re.search(r'<table id="sweep-summary-table">(.*?)</table>', page(sweep_dir))
    assert table
    rows = re.findall(r"<tr><td>(.*?)</td></tr>", table.group(1))
    # one row per policy and swept duration (the list axis), 8 seeds each
    assert len(rows) == len(summary) == 4
    assert list(summary.columns[:3]) == ["policy", "mission.duration_s", "missions"]
    for row, (_, want) in zip(rows, summary.iterrows(), strict=True):
        cells = row.split("</td><td>")
        assert cells[0] == want["policy"] and int(cells[2]) == want["missions"] == 8
        assert float(cells[1]) == want["mission.duration_s"]
        assert cells[3] == (
            f"{want['total_downloaded_mbit_mean']:.1f} ± {want['total_downloaded_mbit_ci95']:.1f}"
        )
        assert cells[4] == f"{want['completion_mean']:.3f} ± {want['completion_ci95']:.3f}"
        assert len(cells) == 3 + 7  # the seven headline metrics
    results = pd.read_parquet(sweep_dir / "results.parquet")
    mine = results[(results["policy"] == "hgad") & (results["mission.duration_s"] == 160)]
    row = summary[(summary["policy"] == "hgad") & (summary["mission.duration_s"] == 160)]
    assert float(row["total_downloaded_mbit_mean"].iloc[0]) == pytest.approx(
        mine["total_downloaded_mbit"].mean()
    )


def test_without_summary_csv_the_rows_give_the_same_table(sweep_dir: Path, tmp_path: Path) -> None:
    """summary.csv lost: the table comes from results.parquet, split by the list axis as
    summary.csv is (the drawn buffers, varying per mission, are no level)."""
    copy = tmp_path / "sw"
    shutil.copytree(sweep_dir, copy)
    (copy / "summary.csv").unlink()
    assert run_cli("report", copy, "--no-pdf").returncode == 0

    def rows(text: str) -> list[str]:
        table = re.search(r'<table id="sweep-summary-table">(.*?)</table>', text)
        assert table
        return re.findall(r"<tr><td>(.*?)</td></tr>", table.group(1))

    assert "no complete summary.csv" in page(copy)
    assert rows(page(copy)) == rows(page(sweep_dir)) and len(rows(page(copy))) == 4


def independent_gain(results: pd.DataFrame, policy: str, baseline: str) -> dict[str, float]:
    """Pairs by construction of SWEEP: one mission per (seed, duration) and policy."""
    keys = ["seed", "mission.duration_s"]
    mine = results[results["policy"] == policy].set_index(keys)["total_downloaded_mbit"]
    base = results[results["policy"] == baseline].set_index(keys)["total_downloaded_mbit"]
    gain = (mine - base.reindex(mine.index)).to_numpy()
    low, _ = stats.t.interval(0.95, gain.size - 1, loc=gain.mean(), scale=stats.sem(gain))
    return {
        "n": gain.size,
        "mean": gain.mean(),
        "ci95": gain.mean() - low,
        "wins": np.mean(gain > 1e-6),
        "losses": np.mean(gain < -1e-6),
    }


@pytest.mark.parametrize("baseline", [None, "hgad"])
def test_paired_gains_match_an_independent_computation(
    sweep_dir: Path, tmp_path: Path, baseline: str | None
) -> None:
    folder = sweep_dir
    if baseline is not None:  # another copy: --baseline and --no-pdf
        folder = tmp_path / "sw"
        shutil.copytree(sweep_dir, folder)
        shutil.rmtree(folder / "figures")
        done = run_cli("report", folder, "--baseline", baseline, "--no-pdf")
        assert done.returncode == 0, done.stderr
        assert not list((folder / "figures").glob("*.pdf"))
    results = pd.read_parquet(folder / "results.parquet")
    base = baseline or "greedy"  # default: greedy when present
    policy = "hgad" if base == "greedy" else "greedy"
    text = page(folder)
    assert f"Baseline <b>{base}</b>" in text and "16 pair sets" in text
    rows = gain_rows(text)
    assert set(rows) == {policy}
    got, want = rows[policy], independent_gain(results, policy, base)
    assert int(got["n"]) == want["n"] == 16
    for key in ("mean", "ci95", "wins", "losses"):
        assert float(got[key]) == pytest.approx(want[key], rel=1e-9, abs=1e-12), key
    cells = got["cells"].split("|")
    assert cells[2] == f"{want['mean']:+.2f}" and cells[3] == f"{want['ci95']:.2f}"
    assert cells[6] == f"{100 * want['wins']:.1f}%" and cells[7] == f"{100 * want['losses']:.1f}%"


def synthetic(folder: Path, policies: list[str], paired: bool) -> Path:
    rng = np.random.default_rng(0)
    rows = []
    for i in range(6):
        for j, policy in enumerate(policies):
            rows.append(
                {
                    "mission_index": len(rows),
                    "mission_id": f"m{len(rows)}",
                    "policy.name": policy,
                    "seed": i if paired else 10 * i + j,
                    "scenario": "synthetic",
                    "policy": policy,
                    "total_downloaded_mbit": float(rng.uniform(100, 200)),
                    "completion": float(rng.uniform(0, 1)),
                }
            )
    folder.mkdir()
    pd.DataFrame(rows).to_parquet(folder / "results.parquet", index=False)
    return folder


def test_unpaired_and_single_policy_sweeps_still_report(tmp_path: Path) -> None:
    unpaired = synthetic(tmp_path / "u", ["a", "b"], paired=False)
    assert run_cli("report", unpaired, "--no-pdf").returncode == 0
    text = page(unpaired)
    assert "No paired missions" in text and "no complete summary.csv" in text
    assert "No swept numeric parameter" in text
    single = synthetic(tmp_path / "s", ["greedy"], paired=True)
    assert run_cli("report", single, "--no-pdf").returncode == 0
    assert "One policy only" in page(single)
    done = run_cli("report", single, "--baseline", "hgad")
    assert done.returncode == 2 and "allowed: greedy" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_broken_and_foreign_folders_get_one_line(tmp_path: Path) -> None:
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "results.parquet").write_bytes(b"not parquet")
    done = run_cli("report", broken)
    assert done.returncode == 2 and "results.parquet: cannot read" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    empty = tmp_path / "empty"
    empty.mkdir()
    done = run_cli("report", empty)
    assert done.returncode == 2 and "not a run folder" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_large_ecdfs_and_dots_come_from_a_histogram_and_a_sample(tmp_path: Path) -> None:
    """Past EXACT_VALUES a policy's ECDF is read at the upper edges of equal bins (the
    fraction of values at or below each edge, exactly) and its dots are a sample of DOTS."""
    from skymule.report import sweep_query
    from skymule.report.sweep import read_results

    folder = synthetic(tmp_path / "big", ["greedy", "hgad"], paired=True)
    rng = np.random.default_rng(3)
    values = rng.lognormal(5.0, 1.0, 50_000)
    frame = pd.DataFrame(
        {
            "mission_index": np.arange(values.size),
            "policy": np.where(np.arange(values.size) % 2 == 0, "greedy", "hgad"),
            "total_downloaded_mbit": values,
        }
    )
    frame.to_parquet(folder / "results.parquet", index=False)
    results = read_results(folder)
    with sweep_query.results_query(results.path, results.schema) as query:
        found = query.distribution("total_downloaded_mbit", "policy")
    for policy, dist in found.items():
        mine = frame.loc[frame["policy"] == policy, "total_downloaded_mbit"].to_numpy()
        assert dist.n == mine.size > sweep_query.EXACT_VALUES
        assert dist.ecdf_x.size <= sweep_query.ECDF_BINS and dist.ecdf_y[-1] == 1.0
        at_or_below = (mine[None, :] <= dist.ecdf_x[:-1, None]).mean(axis=1)
        np.testing.assert_allclose(dist.ecdf_y[:-1], at_or_below, atol=1 / mine.size)
        assert dist.dots.size == sweep_query.DOTS and np.isin(dist.dots, mine).all()
        q1, med, q3 = np.percentile(mine, [25, 50, 75])
        assert (dist.box["q1"], dist.box["med"], dist.box["q3"]) == pytest.approx((q1, med, q3))
        inside = mine[(mine >= q1 - 1.5 * (q3 - q1)) & (mine <= q3 + 1.5 * (q3 - q1))]
        assert (dist.box["whislo"], dist.box["whishi"]) == (inside.min(), inside.max())
        assert dist.mean == pytest.approx(mine.mean(), rel=1e-12)

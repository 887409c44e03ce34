"""The sweep result store: Parquet parts written atomically, resume, consolidation, summary.

Layout of a sweep folder ``DIR``::

    DIR/results/part-00000.parquet ...   one part per finished chunk (tmp file + os.replace)
    DIR/results.parquet                  every mission of the sweep exactly once
    DIR/summary.csv                      per policy: missions, mean and 95% CI per metric

A part is either complete or absent (a killed sweep leaves at most a ``*.tmp`` file, which is
ignored and overwritten), so the mission ids in the parts are exactly the missions done.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from skymule.metrics import HEADLINE_METRICS

PARTS = "results"
RESULTS = "results.parquet"
SUMMARY = "summary.csv"
SUMMARY_METRICS = HEADLINE_METRICS


def part_paths(out: Path) -> list[Path]:
    return sorted((out / PARTS).glob("part-*.parquet"))


def done_ids(out: Path) -> set[str]:
    """Mission ids already stored in ``out``'s parts."""
    ids: set[str] = set()
    for path in part_paths(out):
        ids.update(pq.read_table(path, columns=["mission_id"]).column(0).to_pylist())
    return ids


def _atomic_parquet(frame: pd.DataFrame, path: Path) -> None:
    tmp = path.with_name(path.name + ".tmp")
    frame.to_parquet(tmp, index=False)
    with open(tmp, "rb") as handle:
        os.fsync(handle.fileno())
    os.replace(tmp, path)


def write_part(out: Path, frame: pd.DataFrame) -> Path:
    """Store one finished chunk as the next part (atomically)."""
    folder = out / PARTS
    folder.mkdir(parents=True, exist_ok=True)
    existing = part_paths(out)
    number = int(existing[-1].stem.split("-")[1]) + 1 if existing else 0
    path = folder / f"part-{number:05d}.parquet"
    _atomic_parquet(frame, path)
    return path


def consolidate(out: Path, ids: Iterable[str]) -> pd.DataFrame:
    """``results.parquet``: the sweep's missions (``ids``) exactly once, in sweep order."""
    wanted = set(ids)
    frames = []
    for path in part_paths(out):
        frame = pd.read_parquet(path)
        frames.append(frame[frame["mission_id"].isin(wanted)])
    table = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    if len(table):
        table = table.drop_duplicates("mission_id").sort_values("mission_index")
        table = table.reset_index(drop=True)
    _atomic_parquet(table, out / RESULTS)
    return table


def ci95_half_width(values: np.ndarray) -> float:
    """Half-width of the 95% confidence interval of the mean (Student t; NaN for n < 2)."""
    from scipy.stats import t

    values = values[np.isfinite(values)]
    if values.size < 2:
        return float("nan")
    return float(t.ppf(0.975, values.size - 1) * values.std(ddof=1) / np.sqrt(values.size))


def summary_table(results: pd.DataFrame) -> pd.DataFrame:
    """Per policy: number of missions, and mean and 95% CI half-width of each metric."""
    metrics = [m for m in SUMMARY_METRICS if m in results.columns]
    rows = []
    for policy, group in results.groupby("policy", sort=True):
        row: dict[str, object] = {"policy": policy, "missions": len(group)}
        for metric in metrics:
            values = group[metric].to_numpy(float)
            row[f"{metric}_mean"] = float(np.nanmean(values)) if values.size else float("nan")
            row[f"{metric}_ci95"] = ci95_half_width(values)
        rows.append(row)
    return pd.DataFrame(rows)


def write_summary(out: Path, summary: pd.DataFrame) -> Path:
    path = out / SUMMARY
    tmp = path.with_name(path.name + ".tmp")
    summary.to_csv(tmp, index=False)
    os.replace(tmp, path)
    return path

"""What a report reads: one run folder or a compare folder, from files only.

A run folder is :mod:`skymule.io.run_folder`'s (re-exported here); this module adds compare
folders and the AADM score breakdown. They are read off ``slots.csv`` and ``summary.json``,
never recomputed by simulating.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError
from skymule.io.run_folder import HoverSegment as HoverSegment
from skymule.io.run_folder import RunData as RunData
from skymule.io.run_folder import hover_segments as hover_segments
from skymule.io.run_folder import load_run as load_run
from skymule.io.run_folder import read_scenario as read_scenario
from skymule.io.run_folder import run_data as run_data
from skymule.io.runs import check_complete_comparison, is_run_dir
from skymule.io.textfiles import parse_json
from skymule.rules.score import aadm_score_one

COMPARISON_FILE = "comparison.csv"

#: AADM challenge scoring (see ``shared/data/README.md``): mission horizon [s], landing


@dataclass(frozen=True)
class ReportInput:
    """A run folder (one run) or a compare folder (several runs + comparison.csv)."""

    path: Path
    kind: str  # "run" or "compare"
    runs: tuple[RunData, ...]
    comparison: pd.DataFrame | None


def load_input(path: Path) -> ReportInput:
    """A run folder, or a compare folder holding run folders (and ``comparison.csv``)."""
    if is_run_dir(path):
        return ReportInput(path, "run", (load_run(path),), None)
    children = sorted(p for p in path.iterdir() if is_run_dir(p)) if path.is_dir() else []
    if not children:
        raise SkymuleError(
            f"{path}: not a run folder (no summary.json and slots.csv) nor a compare folder "
            "(no run folders inside); make one with `skymule run SCENARIO --out DIR` or "
            "`skymule compare SCENARIO --out DIR`"
        )
    check_complete_comparison(path)
    runs = tuple(load_run(child, child.name) for child in children)
    table_path = path / COMPARISON_FILE
    return ReportInput(path, "compare", runs, read_comparison(table_path))


def read_comparison(table_path: Path) -> pd.DataFrame | None:
    """comparison.csv of a compare folder, or None when there is none."""
    if not table_path.is_file():
        return None
    try:
        return pd.read_csv(table_path)
    except (OSError, ValueError) as exc:  # pandas' parse errors are ValueErrors
        raise SkymuleError(
            f"{table_path}: cannot read ({str(exc).splitlines()[0]}); rewrite it with "
            "`skymule compare` or delete it"
        ) from None


BOUND_FILE = "bound.json"
"""The bound record ``compare`` writes next to ``comparison.csv`` (with its warnings)."""


def bound_warnings(folder: Path) -> tuple[str, ...]:
    """The conditions of the bound in ``folder/bound.json`` that fail for this mission (one
    line each; a bound with any is not a valid upper bound and is drawn as such), or ``()``
    without a bound file. A bound file that cannot be read is itself the warning."""
    path = folder / BOUND_FILE
    if not path.is_file():
        return ()
    try:
        data = parse_json(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        return (f"{path} cannot be read ({exc}): the bound is unchecked",)
    warnings = data.get("warnings", []) if isinstance(data, dict) else None
    if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings):
        return (f"{path}: 'warnings' is not a list of lines: the bound is unchecked",)
    return tuple(warnings)


def comparison_bound(comparison: pd.DataFrame | None) -> float | None:
    """The upper bound [Mbit] ``compare`` put in comparison.csv (one scenario, one bound),
    or None (no bound, a source comparison with one per source, or no comparison.csv)."""
    if comparison is None or "upper_bound_mbit" not in comparison or "source" in comparison:
        return None
    values = comparison["upper_bound_mbit"].dropna().unique()
    return float(values[0]) if len(values) == 1 else None


@dataclass(frozen=True)
class ScoreBreakdown:
    """AADM challenge score of a run (the rule in force): S = S1 + S2.

    Attributes:
        download_points: S2 = 100 x downloaded / total.
        time_bonus: S1 = max(0, window - t1) if everything was downloaded, else 0.
        landing_penalty: always 0 (the rule in force has no landing term; kept for the
            score figure's stacked bars).
        completed_at_s: t1 when everything was downloaded, else None.
        end_distance_m: horizontal distance from home at the end [m] (the testbed requires
            landing within 5 m; not part of the score).
        reported: ``aadm_score`` from summary.json when the run wrote one.
    """

    download_points: float
    time_bonus: float
    landing_penalty: float
    completed_at_s: float | None
    end_distance_m: float
    reported: float | None

    @property
    def total(self) -> float:
        return self.download_points + self.time_bonus - self.landing_penalty


def score_breakdown(run: RunData) -> ScoreBreakdown:
    """The AADM score's parts: from summary.json, or computed from slots.csv's downloads."""
    summary, slots = run.summary, run.slots
    if all(key in summary for key in ("aadm_s1", "aadm_s2", "aadm_t1_s", "aadm_complete")):
        parts = {key: summary[key] for key in ("aadm_s1", "aadm_s2", "aadm_t1_s", "aadm_complete")}
    else:
        total = float(summary.get("total_buffer_mbit", 0.0)) * 1e6
        per_slot = slots["downloaded_mbit"].to_numpy(float) * 1e6
        parts = dict(aadm_score_one(per_slot, total, run.slot_s))
    if "distance_to_home_m" in summary:
        end_distance = float(summary["distance_to_home_m"])
    elif slots.empty:
        end_distance = 0.0
    else:
        last = slots[["x_m", "y_m"]].to_numpy(float)[-1]
        end_distance = float(np.hypot(*(last - run.site.home_xy_m)))
    reported = summary.get("aadm_score")
    return ScoreBreakdown(
        download_points=float(parts["aadm_s2"]),
        time_bonus=float(parts["aadm_s1"]),
        landing_penalty=0.0,
        completed_at_s=float(parts["aadm_t1_s"]) if parts["aadm_complete"] else None,
        end_distance_m=end_distance,
        reported=float(reported) if isinstance(reported, int | float) else None,
    )

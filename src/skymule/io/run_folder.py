"""A run folder as the readers above the run record take it (exports, reports): its summary,
slot table, scenario and site, read from files only and validated, plus what several of them
derive from the slot table (hover segments)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError
from skymule.io.runs import read_run, read_run_scenario, sensor_names_of
from skymule.io.site import SiteGeometry, site_geometry


@dataclass(frozen=True)
class RunData:
    """One run folder's files."""

    path: Path
    label: str
    summary: dict[str, Any]
    slots: pd.DataFrame
    scenario: dict[str, Any]
    site: SiteGeometry

    @property
    def sensor_names(self) -> list[str]:
        return sensor_names_of(self.slots)

    @property
    def slot_s(self) -> float:
        return float(self.summary.get("slot_s", 1.0))


def read_scenario(run_dir: Path) -> dict[str, Any]:
    """The run's ``scenario.json`` (validated as a scenario), or ``{}`` when it has none."""
    return read_run_scenario(run_dir)


def load_run(run_dir: Path, label: str | None = None) -> RunData:
    """Read a run folder, validated (one clear line if it is not one or is damaged)."""
    summary, slots = read_run(run_dir)
    if "uav" in slots.columns:  # several UAVs: these panels are one UAV's (docs/fleet.md)
        raise SkymuleError(
            f"{run_dir}: a run of several UAVs (slots.csv has a uav column); this reader covers "
            "one UAV: `skymule report` gives the fleet report (skymule.report.fleet_inputs)"
        )
    return run_data(run_dir, summary, slots, label)


def run_data(
    run_dir: Path, summary: dict[str, Any], slots: pd.DataFrame, label: str | None
) -> RunData:
    """:class:`RunData` of a run folder whose summary and slots are read and checked."""
    scenario = read_run_scenario(run_dir)
    return RunData(
        path=run_dir,
        label=label or str(summary.get("policy", run_dir.name)),
        summary=summary,
        slots=slots,
        scenario=scenario,
        site=site_geometry(scenario, run_dir),
    )


@dataclass(frozen=True)
class HoverSegment:
    """Consecutive hovering slots serving one sensor at one place."""

    sensor: str
    start_s: float
    duration_s: float
    x_m: float
    y_m: float
    z_m: float
    downloaded_mbit: float


def hover_segments(slots: pd.DataFrame, slot_s: float) -> list[HoverSegment]:
    """Hover segments of a slot table (``hovering`` column; none if it is absent)."""
    if "hovering" not in slots or slots.empty:
        return []
    hovering = slots["hovering"].to_numpy(int) > 0
    served = slots["served"].to_numpy(str)
    key = np.where(hovering, served, "\0")
    boundaries = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    ends = np.r_[boundaries[1:], len(key)]
    segments = []
    z = slots["z_m"].to_numpy(float) if "z_m" in slots else np.zeros(len(slots))
    for start, end in zip(boundaries, ends, strict=True):
        if not hovering[start]:
            continue
        segments.append(
            HoverSegment(
                sensor=str(served[start]),
                start_s=float(slots["t_s"].iloc[start]),
                duration_s=float((end - start) * slot_s),
                x_m=float(slots["x_m"].iloc[start]),
                y_m=float(slots["y_m"].iloc[start]),
                z_m=float(z[start]),
                downloaded_mbit=float(slots["downloaded_mbit"].iloc[start:end].sum()),
            )
        )
    return segments

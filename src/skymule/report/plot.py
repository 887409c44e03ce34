"""``skymule plot DIR``: a run folder's figures next to its files (the report's own panels).

Reads the folder's files only; drawing is :mod:`skymule.report.figures` and the report's
panels (:mod:`skymule.report.html`), so ``plot`` and ``report`` look the same.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from skymule.report.style import DEFAULT_DPI

__all__ = ["PLOT_FILES", "plot_run"]

PLOT_FILES = {"download": "download", "snr-cdf": "snr_cdf", "trajectory": "trajectory"}


def plot_run(
    run_dir: Path,
    summary: dict[str, Any],
    slots: pd.DataFrame,
    *,
    formats: tuple[str, ...] = ("png",),
    dpi: int = DEFAULT_DPI,
) -> list[Path]:
    """Write the run's figures next to its files, in each of ``formats``; returns the paths.

    ``download`` and ``snr_cdf`` always, ``trajectory`` when the run has its scenario.json
    (the map needs the site). Same panels, size and style as ``skymule report``.
    """
    if "uav" in slots.columns:  # several UAVs: one map, one colour per UAV (docs/fleet.md)
        from skymule.report.fleet import plot_fleet_run

        return plot_fleet_run(run_dir, summary, slots, formats=formats, dpi=dpi)
    from skymule.io.runs import SCENARIO_FILE
    from skymule.io.site import site_geometry
    from skymule.report.html import PER_RUN_PANELS, render_panel
    from skymule.report.inputs import RunData, read_scenario

    scenario = read_scenario(run_dir)
    run = RunData(
        path=run_dir,
        label=str(summary.get("policy", run_dir.name)),
        summary=summary,
        slots=slots,
        scenario=scenario,
        site=site_geometry(scenario, run_dir),
    )
    has_site = (run_dir / SCENARIO_FILE).is_file()
    written: list[Path] = []
    for spec in PER_RUN_PANELS:
        stem = PLOT_FILES.get(spec.key)
        if stem is None or (spec.key == "trajectory" and not has_site):
            continue
        paths = render_panel(spec, (run,), run_dir, formats=formats, dpi=dpi, stem=stem)
        written += list(paths.values())
    return written

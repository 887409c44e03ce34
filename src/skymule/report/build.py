"""``skymule report DIR``: the report of whatever folder DIR is (run, compare or sweep; one
UAV or several)."""

from __future__ import annotations

from pathlib import Path

from skymule.io.runs import is_run_dir
from skymule.report.fleet_html import build_fleet_report
from skymule.report.fleet_inputs import holds_fleet_runs
from skymule.report.html import build_run_report
from skymule.report.sweep import build_sweep_report, is_sweep_dir


def build_report(folder: Path, pdf: bool = True, baseline: str | None = None) -> Path:
    """Write ``folder/report.html`` (and ``folder/figures/*.png|pdf``); returns the HTML path.

    ``pdf=False`` skips the vector PDFs (faster; the HTML only embeds the PNGs). A sweep
    folder (``results.parquet``) gets the sweep report (:mod:`skymule.report.sweep`), with
    ``baseline`` as the policy the paired gains are taken over. A run of several UAVs, or a
    compare folder of such runs, gets the fleet report (:mod:`skymule.report.fleet_html`); a
    compare folder mixing fleet and single-UAV runs is one line.
    """
    if is_sweep_dir(folder) and not is_run_dir(folder):
        return build_sweep_report(folder, pdf=pdf, baseline=baseline)
    if holds_fleet_runs(folder):
        return build_fleet_report(folder, pdf=pdf)
    return build_run_report(folder, pdf=pdf)

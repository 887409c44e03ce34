"""``skymule report DIR``: the report of whatever folder DIR is (run, compare, sweep or
sim2real; one UAV or several), written whole or not at all."""

from __future__ import annotations

from pathlib import Path

from skymule.io.atomic import commit_staged, staging_folder
from skymule.io.runs import is_run_dir
from skymule.report.fleet_html import build_fleet_report
from skymule.report.fleet_inputs import holds_fleet_runs
from skymule.report.html import FIGURES_DIR, REPORT_FILE, build_run_report
from skymule.report.sim2real import build_sim2real_report, is_sim2real_dir
from skymule.report.sweep import build_sweep_report, is_sweep_dir


def build_report(folder: Path, pdf: bool = True, baseline: str | None = None) -> Path:
    """Write ``folder/report.html`` (and ``folder/figures/*.png|pdf``); returns the HTML path.

    ``pdf=False`` skips the vector PDFs (faster; the HTML only embeds the PNGs) and removes
    the PDFs an earlier report left. A sweep folder (``results.parquet``) gets the sweep
    report (:mod:`skymule.report.sweep`), with ``baseline`` as the policy the paired gains are
    taken over. A ``skymule sim2real --out`` folder gets its Sim-to-real report
    (:mod:`skymule.report.sim2real`). A run of several UAVs, or a compare folder of such
    runs, gets the fleet report (:mod:`skymule.report.fleet_html`); a compare folder mixing
    fleet and single-UAV runs is one line.

    The page and its figures are drawn into a hidden staging folder inside ``folder`` and
    moved into place together at the end (:func:`skymule.io.atomic.commit_staged`): a report
    that fails, is interrupted or hits a file-size limit leaves the previous report and
    figures as they were (or none), never a truncated page or a mix of old and new figures.
    """
    if not folder.is_dir():
        return _build(folder, pdf, baseline, None)  # the reader's one-line "not a ... folder"
    with staging_folder(folder, "report") as stage:
        _build(folder, pdf, baseline, stage)
        stale = () if pdf else tuple((folder / FIGURES_DIR).glob("*.pdf"))
        commit_staged(stage, folder, remove=stale)
    return folder / REPORT_FILE


def _build(folder: Path, pdf: bool, baseline: str | None, out: Path | None) -> Path:
    if is_sim2real_dir(folder):
        return build_sim2real_report(folder, pdf=pdf, out=out)
    if is_sweep_dir(folder) and not is_run_dir(folder):
        return build_sweep_report(folder, pdf=pdf, baseline=baseline, out=out)
    if holds_fleet_runs(folder):
        return build_fleet_report(folder, pdf=pdf, out=out)
    return build_run_report(folder, pdf=pdf, out=out)

"""skymule report: self-contained HTML + PNG/PDF figures, from run and compare folders' files."""

from __future__ import annotations

import base64
import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import CliResult, run_cli
from skymule.report.build import build_report
from skymule.report.html import PER_RUN_PANELS
from skymule.report.inputs import hover_segments, load_run, score_breakdown

SHORT = """
name = "short"
seed = 1
[mission]
duration_s = 80
[site]
geofence = "lake-wheeler"
[[sensors]]
name = "LW1"
lat = 35.727451
lon = -78.695974
buffer_mbit = 150
[[sensors]]
name = "LW3"
lat = 35.724933
lon = -78.691912
buffer_mbit = 300
[trajectory]
mode = "fixed"
waypoints = [[0, 0, 30], [6, -70, 30], [148, -160, 30]]
"""
SECTIONS = ("summary", "score", "interactive", "scenario", *(p.key for p in PER_RUN_PANELS))


def skymule(*args: str, cwd: Path) -> CliResult:
    return run_cli(*args, cwd=cwd)


@pytest.fixture(scope="module")
def compare_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A compare folder made by the CLI, then moved: reports must need only its files."""
    work = tmp_path_factory.mktemp("made")
    (work / "short.toml").write_text(SHORT)
    done = skymule("compare", "short.toml", "--out", "cmp", cwd=work)
    assert done.returncode == 0, done.stderr
    moved = tmp_path_factory.mktemp("copied") / "cmp"
    shutil.copytree(work / "cmp", moved)
    shutil.rmtree(work)
    done = skymule("report", str(moved), cwd=moved.parent)
    assert done.returncode == 0, done.stderr
    return moved


def embedded_pngs(page: str) -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(r'src="data:image/png;base64,([^"]+)"', page)]


def test_compare_report_is_self_contained_with_every_section(compare_dir: Path) -> None:
    page = (compare_dir / "report.html").read_text()
    for section in (*SECTIONS, "comparison"):
        assert f'<section id="{section}">' in page, section
    # nothing fetched from anywhere: no http(s) URLs in src/href, no external scripts/styles
    assert not re.search(r'(src|href)="(https?:)?//', page)
    assert "<link" not in page
    pngs = embedded_pngs(page)
    assert len(pngs) == len(PER_RUN_PANELS) + 2  # + score + policy bars
    assert all(p.startswith(b"\x89PNG") for p in pngs)
    # both policies side by side in the tables and the interactive view
    assert page.count('class="traj"') == 2
    assert ">greedy<" in page and ">hgad<" in page


def test_report_tables_echo_summary_and_scenario(compare_dir: Path) -> None:
    page = (compare_dir / "report.html").read_text()
    for policy in ("greedy", "hgad"):
        summary = json.loads((compare_dir / policy / "summary.json").read_text())
        assert f"{summary['total_downloaded_mbit']:.1f}" in page
    assert "&quot;waypoints&quot;" in page  # scenario.json echoed (escaped)
    data = re.search(r'id="slot-data">(.*?)</script>', page, re.S)
    assert data is not None
    slots = json.loads(data.group(1))
    hgad = pd.read_csv(compare_dir / "hgad" / "slots.csv")
    assert len(slots["1"]["t"]) == len(hgad)
    assert slots["1"]["remaining"]["LW3"][-1] == pytest.approx(
        hgad["remaining_mbit_LW3"].iloc[-1], abs=0.01
    )


def test_figures_written_as_png_and_vector_pdf(compare_dir: Path) -> None:
    for key in ("trajectory", "download", "remaining", "snr", "snr-cdf", "score", "policies"):
        png = compare_dir / "figures" / f"{key}.png"
        pdf = compare_dir / "figures" / f"{key}.pdf"
        assert png.read_bytes()[:4] == b"\x89PNG", key
        head = pdf.read_bytes()
        assert head[:5] == b"%PDF-", key
        assert b"/Subtype /Image" not in head, f"{key}.pdf should be vector, not a raster"


def test_single_run_report(tmp_path: Path, compare_dir: Path) -> None:
    run = tmp_path / "hgad"
    shutil.copytree(compare_dir / "hgad", run)
    out = build_report(run, pdf=False)
    page = out.read_text()
    for section in SECTIONS:
        assert f'<section id="{section}">' in page, section
    assert '<section id="comparison">' not in page
    assert page.count('class="traj"') == 1
    assert 'class="fence"' in page  # built-in geofence resolves wherever the folder lives
    assert not list((run / "figures").glob("*.pdf"))


def test_hover_segments_and_score_read_from_files(compare_dir: Path) -> None:
    run = load_run(compare_dir / "hgad")
    segments = hover_segments(run.slots, run.slot_s)
    assert segments, "HGAD hovers near LW1 in this scenario"
    assert sum(s.duration_s for s in segments) == pytest.approx(run.summary["hover_time_s"])
    assert sum(s.downloaded_mbit for s in segments) <= run.summary["total_downloaded_mbit"] + 1e-9
    score = score_breakdown(run)
    assert score.download_points == pytest.approx(100 * run.summary["completion"])
    assert score.completed_at_s is not None  # HGAD empties both buffers on this path
    left = run.slots[["remaining_mbit_LW1", "remaining_mbit_LW3"]].sum(axis=1).to_numpy()
    assert left[int(score.completed_at_s) - 1] == 0.0 < left[int(score.completed_at_s) - 2]
    assert score.time_bonus == pytest.approx(500.0 - score.completed_at_s)  # AADM rule in force
    end = run.slots[["x_m", "y_m"]].to_numpy()[-1]
    assert score.end_distance_m == pytest.approx(
        run.summary.get("distance_to_home_m", np.hypot(*end)), abs=0.5
    )
    if score.reported is not None:  # the run's own AADM score agrees with the breakdown
        assert score.total == pytest.approx(score.reported, abs=1e-6)


def test_score_time_bonus_when_everything_downloaded(tmp_path: Path, compare_dir: Path) -> None:
    run_dir = tmp_path / "done"
    shutil.copytree(compare_dir / "greedy", run_dir)
    # a run folder without the score's parts: they are computed from slots.csv's downloads
    summary = json.loads((run_dir / "summary.json").read_text())
    for key in ("aadm_s1", "aadm_s2", "aadm_t1_s", "aadm_complete"):
        summary.pop(key)
    (run_dir / "summary.json").write_text(json.dumps(summary))
    slots = pd.read_csv(run_dir / "slots.csv")
    before = slots.loc[slots.index < 9, "downloaded_mbit"].sum()
    slots.loc[9, "downloaded_mbit"] = summary["total_buffer_mbit"] - before  # all by slot 9
    slots.loc[slots.index > 9, "downloaded_mbit"] = 0.0
    # the edited downloads no longer match summary.json: handed to the score directly
    score = score_breakdown(replace(load_run(compare_dir / "greedy"), summary=summary, slots=slots))
    assert score.completed_at_s == 10.0  # end of slot 9
    assert score.time_bonus == pytest.approx(490.0)  # 500 - t1


def test_not_a_run_folder_is_one_line_error(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    done = skymule("report", str(tmp_path / "empty"), cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1
    assert "not a run folder" in done.stderr and "Traceback" not in done.stderr


def test_missing_geofence_file_is_a_note_not_an_error(tmp_path: Path, compare_dir: Path) -> None:
    run = tmp_path / "run"
    shutil.copytree(compare_dir / "greedy", run)
    scenario = json.loads((run / "scenario.json").read_text())
    scenario["site"]["geofence"] = "gone/fence.kml"
    (run / "scenario.json").write_text(json.dumps(scenario))
    page = build_report(run, pdf=False).read_text()
    assert "gone/fence.kml" in page and 'class="note"' in page
    assert 'class="fence"' not in page

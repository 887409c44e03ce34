"""Figures fit for a paper: one style for plot and report, print size, distinct colours, words.

Issue 13 item 10. The pictures themselves are looked at through the browser test's screenshots
(test-artifacts/figures/); these tests pin what can be checked without eyes.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import matplotlib.colors as mcolors
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from matplotlib.figure import Figure
from PIL import Image

from conftest import run_cli
from skymule.errors import SkymuleError
from skymule.report.channel import plot_snr_cdf_by_source
from skymule.report.figures import draw_cumulative_download, draw_snr_cdf
from skymule.report.html import share_twin_axes
from skymule.report.inputs import load_run, score_breakdown
from skymule.report.panels import draw_flight_map, draw_policy_bars, draw_score, draw_snr_time
from skymule.report.plot import plot_run
from skymule.report.resilience import plot_resilience
from skymule.report.style import (
    DISTANCE_STYLE,
    NEUTRAL,
    PANEL_WIDTH_IN,
    TOTAL_STYLE,
    _legend_entries,
    grid_shape,
    label_height,
    label_outer_panels,
    panel_figure,
    parameter_label,
    parse_formats,
    policy_styles,
    scenario_description,
    sensor_colours,
    wrap_title,
)
from skymule.report.sweep import STRIP_POINTS, Results, strip_sample, sweep_title
from skymule.report.sweep_query import results_query

SCENARIO = """
name = "my-scenario-id"
[mission]
duration_s = 60
[site]
geofence = "lake-wheeler"
[[sensors]]
name = "LW1"
lat = 35.727451
lon = -78.695974
buffer_mbit = 100
[[sensors]]
name = "LW3"
lat = 35.724933
lon = -78.691912
buffer_mbit = 200
[trajectory]
mode = "fixed"
waypoints = [[0, 0, 30], [6, -70, 30], [148, -160, 30]]
"""


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """greedy and hgad runs of a short fixed path (greedy never hovers, hgad does)."""
    work = tmp_path_factory.mktemp("figures")
    (work / "s.toml").write_text(SCENARIO)
    run_cli("compare", "s.toml", "--out", "cmp", cwd=work, check=True)
    return work / "cmp"


def _rgb(colour: str) -> np.ndarray:
    return np.array(mcolors.to_rgb(colour))


@pytest.mark.parametrize("n", [4, 8, 9, 16, 17, 30])
def test_sensor_colours_stay_distinct_and_never_look_like_the_lines(n: int) -> None:
    names = [f"S{i}" for i in range(n)]
    colours = sensor_colours(names)
    rgb = np.array([_rgb(c) for c in colours.values()])
    gaps = np.linalg.norm(rgb[:, None] - rgb[None, :], axis=2)[np.triu_indices(n, 1)]
    assert gaps.min() > 0.05, f"two of {n} sensors look alike"
    for line in (DISTANCE_STYLE["color"], TOTAL_STYLE["color"], NEUTRAL):
        assert np.linalg.norm(rgb - _rgb(line), axis=1).min() > 0.2, line
    if n <= 16:  # the fixed palette: a sensor's colour does not depend on how many follow
        assert sensor_colours(names[:3]) == {k: colours[k] for k in names[:3]}


def test_formats_parse_and_refuse_with_one_line() -> None:
    assert parse_formats("png,pdf,svg") == ("png", "pdf", "svg")
    assert parse_formats(" PNG, .svg ") == ("png", "svg")
    for bad in ("jpg", "png,,pdf", ""):
        with pytest.raises(SkymuleError, match="allowed: a comma-separated list of png, pdf, svg"):
            parse_formats(bad)


def test_plot_writes_every_format_at_print_size(runs: Path, tmp_path: Path) -> None:
    run = load_run(runs / "hgad")
    folder = tmp_path / "hgad"
    shutil.copytree(runs / "hgad", folder)
    paths = plot_run(folder, run.summary, run.slots, formats=("png", "pdf", "svg"), dpi=300)
    names = sorted(p.name for p in paths)
    stems = ("download", "snr_cdf", "trajectory")
    assert names == sorted(f"{s}.{f}" for s in stems for f in ("png", "pdf", "svg"))
    for stem in stems:
        with Image.open(folder / f"{stem}.png") as image:
            width_px = image.size[0]
        # 3.5 in at 300 dpi, give or take the tight bounding box
        assert 0.9 * PANEL_WIDTH_IN * 300 < width_px < 1.1 * PANEL_WIDTH_IN * 300, stem
        assert (folder / f"{stem}.pdf").read_bytes()[:5] == b"%PDF-"
        assert "<svg" in (folder / f"{stem}.svg").read_text()[:2000]


def test_plot_and_report_draw_the_same_figure(runs: Path, tmp_path: Path) -> None:
    """`plot` renders the report's own panel: the same pixels for the same run."""
    folder = tmp_path / "cmp"
    shutil.copytree(runs, folder)
    run = load_run(folder / "greedy")
    plot_run(folder / "greedy", run.summary, run.slots, formats=("png",), dpi=200)
    run_cli("report", str(folder / "greedy"), "--no-pdf", check=True)
    with (
        Image.open(folder / "greedy" / "download.png") as one,
        Image.open(folder / "greedy" / "figures" / "download.png") as other,
    ):
        plotted, reported = np.asarray(one), np.asarray(other)
    assert plotted.shape == reported.shape and (plotted == reported).all()


def _legend_labels(draw: object, *args: object) -> list[str]:
    fig, (ax,) = panel_figure(1, 3.0)
    draw(ax, *args)  # type: ignore[operator]
    labels = _legend_entries(fig)[1]
    fig.clf()
    return labels


def test_map_legend_lists_only_what_is_drawn(runs: Path) -> None:
    greedy, hgad = load_run(runs / "greedy"), load_run(runs / "hgad")
    assert greedy.summary["hover_time_s"] == 0 and hgad.summary["hover_time_s"] > 0
    assert "hover point" not in _legend_labels(draw_flight_map, greedy)
    assert "hover point" in _legend_labels(draw_flight_map, hgad)
    for label in ("geofence", "tower", "home", "serving LW1"):
        assert label in _legend_labels(draw_flight_map, greedy)


def test_visit_order_subtitle_only_for_autonomous_runs(runs: Path) -> None:
    run = load_run(runs / "hgad")
    _, (ax,) = panel_figure(1, 3.0)
    draw_flight_map(ax, run, "hgad")
    assert ax.get_title() == "hgad"  # a fixed path: the order is the path's, not a choice
    auto = replace(
        run,
        summary={**run.summary, "visit_order": ["LW3"]},
        site=replace(run.site, mode="autonomous"),
    )
    draw_flight_map(ax, auto, "hgad")
    assert ax.get_title() == "hgad\nvisit order: LW3"


def test_titles_describe_the_scenario_not_its_id(runs: Path) -> None:
    run = load_run(runs / "greedy")
    text = scenario_description(run.scenario, run.summary)
    assert text == "2 sensors, fixed path, free space, 60 s"
    assert "my-scenario-id" not in text
    described = {**run.scenario, "description": "Lake Wheeler, towers LW1 and LW3"}
    assert scenario_description(described, run.summary) == "Lake Wheeler, towers LW1 and LW3"


def test_score_labels_stay_inside_the_axes(runs: Path) -> None:
    loaded = [load_run(runs / p) for p in ("greedy", "hgad")]
    fig, (ax,) = panel_figure(1, 2.9)
    draw_score(ax, [r.label for r in loaded], [score_breakdown(r) for r in loaded])
    fig.canvas.draw()
    box = ax.get_window_extent()
    for text in ax.texts:
        extent = text.get_window_extent()
        assert box.y0 <= extent.y0 and extent.y1 <= box.y1, text.get_text()


@pytest.mark.parametrize(
    ("key", "words"),
    [
        ("sensors[*].buffer_mbit", "buffer [Mbit]"),
        ("mission.duration_s", "mission duration [s]"),
        ("trajectory.speed_mps", "speed [m/s]"),
        ("radio.shadowing_std_db", "shadowing std. dev. [dB]"),
        ("policy.some_gain", "some gain"),
        ("radio.new_thing_db", "new thing [dB]"),
    ],
)
def test_parameters_are_named_in_words_with_units(key: str, words: str) -> None:
    assert parameter_label(key) == words


def test_cdf_panels_share_their_snr_range(runs: Path, tmp_path: Path) -> None:
    greedy, hgad = load_run(runs / "greedy"), load_run(runs / "hgad")
    hgad_slots = hgad.slots.copy()
    hgad_slots["snr_db_LW1"] += 15.0  # a source with a different SNR range
    out = plot_snr_cdf_by_source([("a", greedy.slots), ("b", hgad_slots)], tmp_path / "c.png")
    assert out.is_file()
    fig, axes = panel_figure(2, 2.6, sharex=True, sharey=True)
    draw_snr_cdf(axes[0], greedy.slots)
    draw_snr_cdf(axes[1], hgad_slots)
    assert axes[0].get_xlim() == axes[1].get_xlim()
    assert isinstance(fig, Figure)


def test_plot_cli_still_writes_pngs(runs: Path, tmp_path: Path) -> None:
    folder = tmp_path / "r"
    shutil.copytree(runs / "greedy", folder)
    assert json.loads((folder / "summary.json").read_text())["policy"] == "greedy"
    done = run_cli("plot", str(folder), check=True)
    assert "download.png" in done.stdout and (folder / "trajectory.png").is_file()


def test_plot_command_writes_the_formats_asked_for_and_refuses_bad_ones(tmp_path: Path) -> None:
    from conftest import run_cli

    out = tmp_path / "run"
    run_cli("run", "paper-sim-fixed", "--out", out, check=True)
    run_cli("plot", out, "--format", "png,svg", "--dpi", "150", check=True)
    assert (out / "download.svg").exists() and (out / "download.png").exists()
    for args in (("--format", "gif"), ("--dpi", "5")):
        bad = run_cli("plot", out, *args)
        assert bad.returncode == 2 and bad.stderr.count("\n") == 1


# --- issue 25 item 7: each flaw an IEEE reviewer saw, pinned --------------------------------


def test_many_panels_wrap_into_rows_of_two(runs: Path, tmp_path: Path) -> None:
    """Four sources made a 14-inch row; two a row fit a two-column page (7 in), with one y
    label a row and one x label a column."""
    greedy = load_run(runs / "greedy")
    panels = [(name, greedy.slots) for name in ("fspl", "two-ray", "al-hourani", "3gpp")]
    out = plot_snr_cdf_by_source(panels, tmp_path / "four.png", dpi=100)
    with Image.open(out) as image:
        assert image.size[0] < 1.1 * 2 * PANEL_WIDTH_IN * 100
    assert grid_shape(4) == (2, 2) and grid_shape(3) == (2, 2) and grid_shape(1) == (1, 1)
    fig, axes = panel_figure(3, 2.6, sharex=True, sharey=True)
    for ax in axes:
        draw_snr_cdf(ax, greedy.slots)
    label_outer_panels(axes)
    assert [ax.get_ylabel() for ax in axes] == ["empirical CDF", "", "empirical CDF"]
    assert [ax.get_xlabel() for ax in axes] == ["", "SNR [dB]", "SNR [dB]"]  # 2nd: lowest
    assert len(fig.axes) == 3  # the empty fourth place is left blank


def test_side_by_side_distance_axes_share_one_scale(runs: Path) -> None:
    greedy, hgad = load_run(runs / "greedy"), load_run(runs / "hgad")
    longer = hgad.slots.copy()
    longer["distance_m"] *= 3.0
    fig, axes = panel_figure(2, 2.9, sharex=True, sharey=True)
    draw_cumulative_download(axes[0], greedy.slots)
    draw_cumulative_download(axes[1], longer)
    share_twin_axes(fig, axes)
    twins = [a for a in fig.axes if a not in axes]
    assert len(twins) == 2 and twins[0].get_ylim() == twins[1].get_ylim()
    assert twins[0].get_ylabel() == "" and twins[1].get_ylabel() == "distance flown [m]"


def test_score_legend_names_the_aadm_window_not_completion(runs: Path) -> None:
    loaded = [load_run(runs / p) for p in ("greedy", "hgad")]
    scores = [score_breakdown(r) for r in loaded]
    labels = _legend_labels(draw_score, [r.label for r in loaded], scores, 500.0)
    assert labels[0] == "S2: 100 × share downloaded in the first 500 s"
    assert not any("completion" in label for label in labels)


def test_snr_legend_explains_the_thick_lines(runs: Path) -> None:
    labels = _legend_labels(draw_snr_time, load_run(runs / "hgad"))
    assert {"served (thick)", "not served (thin)"} <= set(labels)


def test_policy_bars_show_the_bound_and_keep_labels_off_the_lines(runs: Path) -> None:
    loaded = [load_run(runs / p) for p in ("greedy", "hgad")]
    labels = _legend_labels(draw_policy_bars, loaded, "", 290.0)
    assert "upper bound" in labels and "total buffer" in labels
    assert label_height(2756.0, [3000.0], 3000.0) == 3000.0  # within 10 %: above the line
    assert label_height(2438.0, [3000.0, None], 3000.0) == 2438.0
    assert label_height(2438.0, [float("nan")], 3000.0) == 2438.0


def test_a_long_title_is_folded_to_the_figure_not_cut(runs: Path) -> None:
    words = "Lake Wheeler, four towers, the lawnmower path flown at 30 m in free space, 500 s"
    folded = wrap_title(words, PANEL_WIDTH_IN).splitlines()
    assert len(folded) > 1 and " ".join(folded) == words
    assert wrap_title("4 sensors, fixed path", PANEL_WIDTH_IN) == "4 sensors, fixed path"


def test_the_report_shows_the_bound_and_each_gap(tmp_path: Path) -> None:
    out = tmp_path / "cmp"
    run_cli("compare", "paper-sim-fixed", "--out", out, check=True)
    run_cli("report", out, "--no-pdf", check=True)
    page = (out / "report.html").read_text()
    table = page[page.index('<table id="gap-table">') :]
    table = table[: table.index("</table>")]
    compared = pd.read_csv(out / "comparison.csv").set_index("policy")
    for policy in ("greedy", "hgad"):
        gap = compared.loc[policy, "gap_to_bound_mbit"]
        assert f"<td>{policy}</td>" in table and f"<td>{gap:.1f}</td>" in table
    assert "<td>3000.0</td>" in table and "upper bound" in page


def test_resilience_figure_tells_every_policy_apart(tmp_path: Path) -> None:
    frame = pd.DataFrame(
        {
            "policy": ["hgad", "hgad", "hgad-robust", "hgad-robust"],
            "level": [0.0, 60.0, 0.0, 60.0],
            "mbit_mean": [2500.0, 2400.0, 2500.0, 2400.0],  # on top of each other
            "mbit_ci95": [50.0, 60.0, 50.0, 60.0],
            "bound_mbit_mean": [2900.0] * 4,
        }
    )
    path = plot_resilience(frame, "mean outage [s]", tmp_path / "r.png", "4 sensors", dpi=100)
    with Image.open(path) as image:
        assert image.size[0] < 1.1 * PANEL_WIDTH_IN * 100
    styles = policy_styles(["hgad", "hgad-robust"])
    assert styles["hgad"]["marker"] != styles["hgad-robust"]["marker"]
    assert styles["hgad"]["ls"] != styles["hgad-robust"]["ls"]


def test_sweep_strips_draw_a_sample_and_titles_name_the_scenario(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    many = rng.normal(size=10_000)
    shown = strip_sample(many, np.random.default_rng(0))
    assert shown.size == STRIP_POINTS and np.isin(shown, many).all()
    assert strip_sample(many[:10], rng).size == 10
    results = pd.DataFrame(
        {
            "scenario": ["paper-sim-fixed"] * 3,
            "mission_time_s": [500.0] * 3,
            "per_sensor_buffer_mbit.LW1": [1.0] * 3,
            "per_sensor_buffer_mbit.LW2": [1.0] * 3,
        }
    )
    results.to_parquet(tmp_path / "results.parquet", index=False)
    stored = Results(tmp_path / "results.parquet", pq.read_schema(tmp_path / "results.parquet"), 3)
    with results_query(stored.path, stored.schema) as query:  # queried, not loaded
        assert sweep_title(query, stored) == "paper-sim-fixed, 2 sensors, 500 s: 3 missions"

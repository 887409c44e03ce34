"""``skymule report DIR``: one self-contained HTML file from a run or compare folder.

The report reads the folder's files only (summary.json, slots.csv, scenario.json,
comparison.csv). Every figure is drawn with matplotlib in the paper style, written to
``DIR/figures/<name>.png`` and ``.pdf`` and embedded in ``DIR/report.html`` as a base64 PNG;
the interactive trajectory view is inline SVG + inline JS. Nothing is fetched: the file works
offline and can be mailed around.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

from matplotlib.axes import Axes
from matplotlib.figure import Figure

from skymule.io import atomic
from skymule.report.figures import draw_cumulative_download, draw_snr_cdf
from skymule.report.inputs import (
    ReportInput,
    RunData,
    ScoreBreakdown,
    bound_warnings,
    comparison_bound,
    load_input,
    score_breakdown,
)
from skymule.report.interactive import SCRIPT, payload_script, trajectory_svg
from skymule.report.panels import (
    draw_flight_map,
    draw_policy_bars,
    draw_remaining,
    draw_score,
    draw_snr_time,
)
from skymule.report.style import (
    PANEL_WIDTH_IN,
    finish_figure,
    grid_shape,
    label_outer_panels,
    panel_figure,
    paper_style,
    report_formats,
    save_figure,
    scenario_description,
)
from skymule.rules.defaults import AADM_WINDOW_S

REPORT_FILE = "report.html"
FIGURES_DIR = "figures"
#: Resolution of the report's PNGs (embedded in the page; the PDFs are vector).
REPORT_DPI = 200
#: CSS pixels per inch: the page shows each figure at its print size.
CSS_PX_PER_IN = 96


Item = TypeVar("Item")


@dataclass(frozen=True)
class PanelSpec(Generic[Item]):
    """A per-run figure: one panel per run (a :class:`RunData`, or a fleet run), runs side by
    side in a compare report."""

    key: str
    title: str
    caption: str
    draw: Callable[[Axes, Item], object]
    height_in: float
    #: panels of a compare figure share their axes ranges (same scale side by side)
    shared: bool = True


PER_RUN_PANELS: tuple[PanelSpec[RunData], ...] = (
    PanelSpec(
        "trajectory",
        "Trajectory",
        "Flown path over the geofence (dashed) and towers (triangles), coloured by the sensor "
        "served; circles are hover points (larger: longer), the star is home.",
        lambda ax, run: draw_flight_map(ax, run, run.label),
        4.2,
        shared=False,  # equal aspect per map (the site sets the extent of each anyway)
    ),
    PanelSpec(
        "download",
        "Cumulative download",
        "Data downloaded from each sensor by the end of every slot; distance flown (black, "
        "dotted) on the right axis.",
        lambda ax, run: draw_cumulative_download(ax, run.slots, run.label),
        2.9,
    ),
    PanelSpec(
        "remaining",
        "Remaining data",
        "Data left in each sensor's buffer at the end of every slot.",
        lambda ax, run: draw_remaining(ax, run, run.label),
        2.6,
    ),
    PanelSpec(
        "snr",
        "SNR over time",
        "SNR to each sensor at the start of every slot; thick where that sensor is served.",
        lambda ax, run: draw_snr_time(ax, run, run.label),
        2.6,
    ),
    PanelSpec(
        "snr-cdf",
        "SNR distribution",
        "Empirical CDF of the SNR to each sensor over the mission.",
        lambda ax, run: draw_snr_cdf(ax, run.slots, run.label),
        2.6,
    ),
)

STYLE = """
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;margin:0 auto;max-width:1200px;
padding:1rem 1.5rem;color:#222;line-height:1.4}
h1{font-size:1.5rem;margin-bottom:.2rem}h2{font-size:1.15rem;border-bottom:1px solid #ddd;
padding-bottom:.2rem;margin-top:2rem}nav a{margin-right:.8rem}
table{border-collapse:collapse;font-size:.85rem;margin:.5rem 0}
th,td{border:1px solid #ccc;padding:.2rem .5rem;text-align:right}th:first-child,td:first-child
{text-align:left}figure{margin:.5rem 0}figure img{max-width:100%;height:auto}
figcaption{font-size:.85rem;color:#555}pre{background:#f6f6f6;padding:.6rem;font-size:.75rem;
max-height:24rem;overflow:auto}.views{display:flex;flex-wrap:wrap;gap:1rem}
.view{border:1px solid #ddd;padding:.4rem}.tip{font-size:.8rem;min-height:2.4em;max-width:560px}
svg.traj{background:#fff;cursor:crosshair;touch-action:none}.note{color:#a33}
.warning{color:#a00;border-left:3px solid #a00;padding-left:.5rem}
"""

SUMMARY_FIELDS: tuple[tuple[str, str, str], ...] = (
    ("total_downloaded_mbit", "downloaded [Mbit]", "{:.1f}"),
    ("total_buffer_mbit", "buffer [Mbit]", "{:.1f}"),
    ("completion", "completion", "{:.3f}"),
    ("handovers", "handovers", "{:d}"),
    ("hover_time_s", "hover [s]", "{:.0f}"),
    ("distance_m", "distance [m]", "{:.0f}"),
    ("mission_time_s", "mission time [s]", "{:.0f}"),
    ("energy_kj", "energy [kJ]", "{:.1f}"),
    ("landed_within_5m", "landed within 5 m of home", "{}"),
    ("distance_to_home_m", "end distance to home [m]", "{:.1f}"),
    ("aadm_score", "AADM score (run)", "{:.1f}"),
)


def format_cell(template: str, value: Any) -> str:
    """``value`` formatted by ``template`` for a table cell (escaped text if it does not fit)."""
    try:
        if template == "{:d}":
            return str(int(value))
        return template.format(value)
    except (TypeError, ValueError):
        return html.escape(str(value))


def table_html(header: list[str], rows: list[list[str]], table_id: str) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>" for row in rows)
    return f'<table id="{table_id}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def summary_table(runs: tuple[RunData, ...]) -> str:
    """Key metrics, one column per run (only rows some run has)."""
    fields = [f for f in SUMMARY_FIELDS if any(f[0] in r.summary for r in runs)]
    rows = [
        [html.escape(label)]
        + [format_cell(fmt, r.summary[key]) if key in r.summary else "-" for r in runs]
        for key, label, fmt in fields
    ]
    visit = [r for r in runs if "visit_order" in r.summary]
    if visit:
        rows.append(
            ["visit order"]
            + [html.escape(" → ".join(map(str, r.summary.get("visit_order", [])))) for r in runs]
        )
    return table_html(["metric", *(r.label for r in runs)], rows, "summary-table")


def sensor_table(runs: tuple[RunData, ...]) -> str:
    """Buffer and downloaded data per sensor, one column per run."""
    names = list(
        dict.fromkeys(n for r in runs for n in r.summary.get("per_sensor_buffer_mbit", {}))
    )
    rows = []
    for name in names:
        buffer = runs[0].summary.get("per_sensor_buffer_mbit", {}).get(name)
        rows.append(
            [html.escape(name), format_cell("{:.1f}", buffer)]
            + [
                format_cell("{:.1f}", r.summary.get("per_sensor_downloaded_mbit", {}).get(name))
                for r in runs
            ]
        )
    header = ["sensor", "buffer [Mbit]", *(f"{r.label} [Mbit]" for r in runs)]
    return table_html(header, rows, "sensor-table")


def score_table(runs: tuple[RunData, ...], scores: list[ScoreBreakdown]) -> str:
    window = run_window_s(runs)
    rows = [
        ["S2 = 100 x downloaded / total", *(f"{s.download_points:.1f}" for s in scores)],
        [
            "all data by [s]",
            *("-" if s.completed_at_s is None else f"{s.completed_at_s:.0f}" for s in scores),
        ],
        [f"S1 = {window:g} - t1 if all downloaded", *(f"{s.time_bonus:.1f}" for s in scores)],
        [
            "end distance to home [m] (testbed: land within 5 m)",
            *(f"{s.end_distance_m:.1f}" for s in scores),
        ],
        ["score", *(f"<b>{s.total:.1f}</b>" for s in scores)],
    ]
    if any(s.reported is not None for s in scores):
        rows.append(
            [
                "score in summary.json",
                *("-" if s.reported is None else f"{s.reported:.1f}" for s in scores),
            ]
        )
    return table_html(["AADM score", *(r.label for r in runs)], rows, "score-table")


def bound_caption(bound: float | None, warnings: Sequence[str], what: str) -> str:
    """The figure caption's words for the bound line: ``what`` when valid; when its
    condition fails, that it is invalid here and why (``bound.json``'s warnings)."""
    if bound is None:
        return ""
    if not warnings:
        return f"; solid: {what}"
    return (
        f"; red dotted: a bound that is NOT valid here, it may be below what a policy can "
        f"download ({'; '.join(warnings)})"
    )


def invalid_bound_note(warnings: Sequence[str]) -> str:
    """A visible paragraph saying the bound and its gaps are not valid here (or "")."""
    if not warnings:
        return ""
    text = "; ".join(warnings)
    return (
        f'<p class="warning"><strong>The bound is not valid for this mission:</strong> '
        f"{html.escape(text)}. Gaps against it are not gaps to the optimum.</p>"
    )


def gap_table(runs: tuple[RunData, ...], bound_mbit: float, valid: bool = True) -> str:
    """Each policy's download against the upper bound on any policy (``compare``'s gap);
    ``valid`` False labels the bound columns as invalid."""
    rows = []
    for run in runs:
        down = float(run.summary.get("total_downloaded_mbit", 0.0))
        gap = bound_mbit - down
        share = f"{100 * gap / bound_mbit:.1f}" if bound_mbit > 0 else "-"
        cells = [f"{down:.1f}", f"{bound_mbit:.1f}", f"{gap:.1f}", share]
        rows.append([html.escape(run.label), *cells])
    header = ["policy", "downloaded [Mbit]", "upper bound [Mbit]", "gap [Mbit]", "gap [%]"]
    if not valid:
        header = [
            "policy", "downloaded [Mbit]", "bound, INVALID here [Mbit]", "gap to it [Mbit]",
            "gap to it [%]",
        ]  # fmt: skip
    return table_html(header, rows, "gap-table")


def _img(png: Path, alt: str, width_in: float | None) -> str:
    data = base64.b64encode(png.read_bytes()).decode("ascii")
    size = f' style="width:{width_in * CSS_PX_PER_IN:.0f}px"' if width_in else ""
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}"{size}>'


def figure_html(key: str, png: Path, caption: str, width_in: float | None = None) -> str:
    """A figure block; ``width_in`` shows it at its print width (CSS inches)."""
    written = [p for p in (png, png.with_suffix(".pdf")) if p.is_file()]
    files = ", ".join(f"{FIGURES_DIR}/{p.name}" for p in written)
    return (
        f'<figure class="fig" data-fig="{key}">{_img(png, caption, width_in)}'
        f"<figcaption>{html.escape(caption)} (files: {html.escape(files)})</figcaption></figure>"
    )


def figure_title(runs: tuple[RunData, ...]) -> str:
    """A figure's title: the scenario in words (the runs of a compare share it)."""
    return scenario_description(runs[0].scenario, runs[0].summary)


def render_panels(
    spec: PanelSpec[Item],
    items: Sequence[Item],
    folder: Path,
    title: str,
    formats: tuple[str, ...],
    dpi: int = REPORT_DPI,
    stem: str | None = None,
) -> dict[str, Path]:
    """Draw ``spec`` for every item side by side, one print-sized panel each, one legend and
    ``title``; returns the written files by format."""
    with paper_style():
        fig, axes = panel_figure(len(items), spec.height_in, sharex=spec.shared, sharey=spec.shared)
        for ax, item in zip(axes, items, strict=True):
            spec.draw(ax, item)
        if spec.shared:
            label_outer_panels(axes)
            share_twin_axes(fig, axes)
        finish_figure(fig, title)
        return save_figure(fig, folder, stem or spec.key, formats, dpi)


def share_twin_axes(fig: Figure, axes: Sequence[Axes]) -> None:
    """Second y axes (the distance flown) of panels on one scale: one range for all, labelled
    on the last column only, as the first axes are (a 1750 m axis next to a 3000 m one would
    read as the same distance)."""
    twins = {
        index: other
        for index, ax in enumerate(axes)
        for other in fig.axes
        if other is not ax and other.get_subplotspec() == ax.get_subplotspec()
    }
    if len(twins) < 2:
        return
    top = max(twin.get_ylim()[1] for twin in twins.values())
    _, columns = grid_shape(len(axes))
    for index, twin in twins.items():
        twin.set_ylim(0, top)
        if (index + 1) % columns and index != len(axes) - 1:  # not the row's last panel
            twin.set_ylabel("")
            twin.tick_params(labelright=False)


def render_panel(
    spec: PanelSpec[RunData],
    runs: tuple[RunData, ...],
    folder: Path,
    pdf: bool = True,
    *,
    formats: tuple[str, ...] | None = None,
    dpi: int = REPORT_DPI,
    stem: str | None = None,
) -> dict[str, Path]:
    """:func:`render_panels` of runs, the scenario as title (``formats`` overrides ``pdf``)."""
    chosen = formats or report_formats(pdf)
    return render_panels(spec, runs, folder, figure_title(runs), chosen, dpi, stem)


def render_bars(
    runs: tuple[RunData, ...],
    folder: Path,
    pdf: bool = True,
    bound_mbit: float | None = None,
    bound_valid: bool = True,
) -> Path:
    with paper_style():
        fig, (ax,) = panel_figure(1, 2.9)
        draw_policy_bars(ax, runs, bound_mbit=bound_mbit, bound_valid=bound_valid)
        finish_figure(fig, figure_title(runs))
        return save_figure(fig, folder, "policies", report_formats(pdf), REPORT_DPI)["png"]


def run_window_s(runs: tuple[RunData, ...]) -> float:
    """The AADM download window of the first run [s] (its scenario's, else the default)."""
    return float(runs[0].scenario.get("mission", {}).get("aadm_window_s") or AADM_WINDOW_S)


def render_score(
    runs: tuple[RunData, ...], scores: list[ScoreBreakdown], folder: Path, pdf: bool = True
) -> Path:
    with paper_style():
        fig, (ax,) = panel_figure(1, 2.9)
        draw_score(ax, [r.label for r in runs], scores, run_window_s(runs))
        finish_figure(fig, "AADM score breakdown", columns=1)
        return save_figure(fig, folder, "score", report_formats(pdf), REPORT_DPI)["png"]


def page_html(
    title: str, intro_html: str, sections: list[tuple[str, str, str]], tail_html: str = ""
) -> str:
    """One self-contained report page: title, ``intro_html`` and a section index in the
    header, then the sections, then ``tail_html`` (inline scripts)."""
    nav = "".join(f'<a href="#{sid}">{html.escape(t)}</a>' for sid, t, _ in sections)
    body = "".join(section_html(sid, t, c) for sid, t, c in sections)
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>"
        f"<header><h1>{html.escape(title)}</h1>{intro_html}"
        f"<nav>{nav}</nav></header><main>{body}</main>{tail_html}</body></html>"
    )


def section_html(section_id: str, title: str, content: str) -> str:
    return f'<section id="{section_id}"><h2>{html.escape(title)}</h2>{content}</section>'


def _scenario_block(report: ReportInput) -> str:
    first = report.runs[0]
    intro = ""
    if report.kind == "compare":
        intro = (
            f"<p>Scenario of <code>{html.escape(first.path.name)}</code>; the runs differ in "
            f"policy: {html.escape(', '.join(r.label for r in report.runs))}.</p>"
        )
    text = json.dumps(first.scenario, indent=2) if first.scenario else "(no scenario.json)"
    return intro + f"<pre>{html.escape(text)}</pre>"


def build_run_report(folder: Path, pdf: bool = True, out: Path | None = None) -> Path:
    """Write ``report.html`` (and ``figures/*.png|pdf``) for a run or compare folder into
    ``out`` (default: ``folder``); returns the HTML path. ``pdf=False`` skips the vector PDFs
    (the HTML only embeds the PNGs)."""
    report = load_input(folder)
    runs = report.runs
    figures = (out or folder) / FIGURES_DIR
    scores = [score_breakdown(r) for r in runs]
    first = runs[0].summary
    title = f"{first.get('scenario', folder.name)}: " + (
        f"{runs[0].label}" if report.kind == "run" else f"{', '.join(r.label for r in runs)}"
    )
    sections: list[tuple[str, str, str]] = [
        ("summary", "Summary", summary_table(runs) + sensor_table(runs)),
        (
            "score",
            "AADM score",
            figure_html(
                "score",
                render_score(runs, scores, figures, pdf),
                "AADM score breakdown",
                PANEL_WIDTH_IN,
            )
            + score_table(runs, scores),
        ),
    ]
    if report.kind == "compare":
        bound = comparison_bound(report.comparison)
        warned = bound_warnings(report.path) if bound is not None else ()
        caption = "Data downloaded per policy, stacked by sensor; dashed: total buffer"
        caption += bound_caption(
            bound, warned, "the upper bound on what any policy can download (skymule bound)"
        )
        sections.append(
            (
                "comparison",
                "Policy comparison",
                invalid_bound_note(warned)
                + figure_html(
                    "policies",
                    render_bars(runs, figures, pdf, bound, bound_valid=not warned),
                    caption + ".",
                    PANEL_WIDTH_IN,
                )
                + (gap_table(runs, bound, valid=not warned) if bound is not None else ""),
            )
        )
    for spec in PER_RUN_PANELS:
        sections.append(
            (
                spec.key,
                spec.title,
                figure_html(
                    spec.key,
                    render_panel(spec, runs, figures, pdf)["png"],
                    spec.caption,
                    PANEL_WIDTH_IN * grid_shape(len(runs))[1],
                ),
            )
        )
    views = "".join(
        f'<div class="view"><b>{html.escape(r.label)}</b><br>{trajectory_svg(r, i)}'
        '<div class="tip">hover over the map for slot details</div></div>'
        for i, r in enumerate(runs)
    )
    sections.insert(
        3 if report.kind == "run" else 4,
        (
            "interactive",
            "Interactive trajectory",
            "<p>Drag to pan, wheel to zoom, double-click to reset; hover for the nearest "
            f'slot.</p><div class="views">{views}</div>',
        ),
    )
    sections.append(("scenario", "Scenario", _scenario_block(report)))
    notes = sorted({note for r in runs for note in r.site.notes})
    note_html = "".join(f'<p class="note">{html.escape(n)}</p>' for n in notes)
    intro = (
        f"<p>skymule report of <code>{html.escape(str(folder))}</code> ({report.kind} folder, "
        f"{len(runs)} run{'s' if len(runs) > 1 else ''}).</p>{note_html}"
    )
    page = page_html(
        title, intro, sections, f"{payload_script(list(runs))}<script>{SCRIPT}</script>"
    )
    return atomic.write_text((out or folder) / REPORT_FILE, page)

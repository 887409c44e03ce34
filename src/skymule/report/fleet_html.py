"""``skymule report DIR`` for runs of several UAVs (``docs/fleet.md``): one self-contained page.

The fleet counterpart of :func:`skymule.report.html.build_run_report`, with the same files
(``DIR/report.html``, ``DIR/figures/<name>.png`` and ``.pdf``) and the same look: the fleet's
totals, one row per UAV (download, lost slots, hover, distance, energy, landing), the Mbit each
UAV took from each sensor, the fleet map, the downloads per sensor stacked by UAV, the
cumulative download per UAV and in total, and the shared buffers over time. A compare folder
of fleet runs (``skymule compare`` on a fleet scenario) puts the runs side by side. Everything
is read from the folder's files (:mod:`skymule.report.fleet_inputs`), never simulated.

Not here (single-UAV views): the AADM score (a one-UAV challenge rule), the SNR panels (one
curve per sensor per UAV would be unreadable) and the interactive map.
"""

from __future__ import annotations

import html
import json
from dataclasses import replace
from pathlib import Path

from matplotlib.axes import Axes

from skymule.io import atomic
from skymule.report.fleet import draw_fleet_trajectory, draw_uav_cumulative, draw_uav_sensor_bars
from skymule.report.fleet_inputs import FleetRun, load_fleet_input
from skymule.report.html import (
    FIGURES_DIR,
    REPORT_FILE,
    PanelSpec,
    bound_caption,
    figure_html,
    format_cell,
    gap_table,
    invalid_bound_note,
    page_html,
    render_bars,
    render_panels,
    sensor_table,
    table_html,
)
from skymule.report.inputs import (
    COMPARISON_FILE,
    bound_warnings,
    comparison_bound,
    read_comparison,
)
from skymule.report.panels import draw_remaining
from skymule.report.style import (
    PANEL_WIDTH_IN,
    grid_shape,
    report_formats,
    scenario_description,
)

#: Fleet totals (top of a fleet summary.json): key, label, format.
FLEET_FIELDS: tuple[tuple[str, str, str], ...] = (
    ("n_uavs", "UAVs", "{:d}"),
    ("total_downloaded_mbit", "downloaded [Mbit]", "{:.1f}"),
    ("total_buffer_mbit", "buffer [Mbit]", "{:.1f}"),
    ("completion", "completion", "{:.3f}"),
    ("lost_slots", "lost slots (sensor won by another UAV)", "{:d}"),
    ("distance_m", "distance, all UAVs [m]", "{:.0f}"),
    ("energy_kj", "energy, all UAVs [kJ]", "{:.1f}"),
    ("mission_time_s", "mission time [s]", "{:.0f}"),
    ("landed_within_5m", "every UAV landed within 5 m of home", "{}"),
)

#: One UAV (an entry of summary.json's ``uavs``): key, column header, format.
UAV_FIELDS: tuple[tuple[str, str, str], ...] = (
    ("total_downloaded_mbit", "downloaded [Mbit]", "{:.1f}"),
    ("lost_slots", "lost slots", "{:d}"),
    ("hover_time_s", "hover [s]", "{:.0f}"),
    ("handovers", "handovers", "{:d}"),
    ("distance_m", "distance [m]", "{:.0f}"),
    ("energy_kj", "energy [kJ]", "{:.1f}"),
    ("landed_within_5m", "landed within 5 m of home", "{}"),
    ("distance_to_home_m", "end distance to home [m]", "{:.1f}"),
)


def _draw_map(ax: Axes, fleet: FleetRun) -> None:
    run = fleet.run
    draw_fleet_trajectory(
        ax, run.slots, run.summary, run.scenario, legend=False, title=run.label, marker_scale=0.4
    )


def _draw_bars(ax: Axes, fleet: FleetRun) -> None:
    buffers = fleet.run.summary.get("per_sensor_buffer_mbit", {})
    draw_uav_sensor_bars(ax, fleet.sensor_mbit(), buffers, fleet.label)


def _draw_cumulative(ax: Axes, fleet: FleetRun) -> None:
    draw_uav_cumulative(ax, fleet.run.slots, list(fleet.uavs), fleet.run.slot_s, fleet.label)


def _draw_shared_buffers(ax: Axes, fleet: FleetRun) -> None:
    # the buffers are shared: every UAV's rows hold the same remaining_mbit_* (after the slot)
    draw_remaining(ax, replace(fleet.run, slots=fleet.slots_of(fleet.uavs[0])), fleet.label)


FLEET_PANELS: tuple[PanelSpec[FleetRun], ...] = (
    PanelSpec(
        "trajectory",
        "Trajectories",
        "Flown paths, one colour per UAV: dots where it served a sensor, crosses where it lost "
        "the sensor it chose to another UAV; stars are the UAVs' homes, triangles the towers.",
        _draw_map,
        4.2,
        shared=False,  # equal aspect per map
    ),
    PanelSpec(
        "uav-sensors",
        "Downloads by sensor and UAV",
        "Data downloaded from each sensor, stacked by the UAV that downloaded it (from "
        "slots.csv); grey dashes: the sensor's buffer.",
        _draw_bars,
        2.9,
    ),
    PanelSpec(
        "download",
        "Cumulative download",
        "Data downloaded by the end of every slot by each UAV and by the whole fleet (grey, "
        "dashed).",
        _draw_cumulative,
        2.9,
    ),
    PanelSpec(
        "remaining",
        "Remaining data",
        "Data left in each sensor's buffer (shared by the UAVs) at the end of every slot.",
        _draw_shared_buffers,
        2.6,
    ),
)


def fleet_title(fleets: tuple[FleetRun, ...]) -> str:
    """A figure's title: the fleet size and the scenario in words."""
    run = fleets[0].run
    uavs = len(fleets[0].uavs)
    return (
        f"{uavs} UAV{'s' if uavs != 1 else ''}: {scenario_description(run.scenario, run.summary)}"
    )


def render_fleet_panel(
    panel: PanelSpec[FleetRun], fleets: tuple[FleetRun, ...], folder: Path, pdf: bool = True
) -> Path:
    """Draw ``panel`` for every run side by side, one legend below, the fleet as title;
    writes ``folder/<key>.png`` (and ``.pdf``) and returns the PNG."""
    return render_panels(panel, fleets, folder, fleet_title(fleets), report_formats(pdf))["png"]


def fleet_table(fleets: tuple[FleetRun, ...]) -> str:
    """The fleet totals, one column per run (only rows some run has)."""
    summaries = [f.run.summary for f in fleets]
    rows = [
        [html.escape(label)] + [format_cell(fmt, s[key]) if key in s else "-" for s in summaries]
        for key, label, fmt in FLEET_FIELDS
        if any(key in s for s in summaries)
    ]
    return table_html(["fleet", *(f.label for f in fleets)], rows, "fleet-table")


def uav_table(fleet: FleetRun, index: int) -> str:
    """One row per UAV (its summary.json entry) and the fleet's row; share of the download."""
    fields = [f for f in UAV_FIELDS if any(f[0] in u for u in fleet.per_uav)]
    total = float(fleet.run.summary.get("total_downloaded_mbit", 0.0))
    rows = []
    for entry in [*fleet.per_uav, {**fleet.run.summary, "uav": "fleet"}]:
        mbit = float(entry.get("total_downloaded_mbit", 0.0))
        share = format_cell("{:.1%}", mbit / total) if total > 0 else "-"
        order = entry.get("visit_order")
        rows.append(
            [html.escape(str(entry["uav"]))]
            + [format_cell(fmt, entry[key]) if key in entry else "-" for key, _, fmt in fields]
            + [share, html.escape(" → ".join(map(str, order))) if order else "-"]
        )
    header = ["UAV", *(label for _, label, _ in fields), "share of fleet", "visit order"]
    return table_html(header, rows, f"uav-table-{index}")


def uav_sensor_table(fleet: FleetRun, index: int) -> str:
    """Mbit each UAV downloaded from each sensor (from slots.csv), the fleet's and the buffers."""
    by_uav = fleet.sensor_mbit()
    summary = fleet.run.summary
    sensors = [str(s) for s in by_uav.columns]
    rows = [
        [html.escape(str(uav))] + [f"{v:.1f}" for v in values.to_numpy(float)]
        for uav, values in by_uav.iterrows()
    ]
    for label, key in (
        ("fleet", "per_sensor_downloaded_mbit"),
        ("buffer", "per_sensor_buffer_mbit"),
    ):
        rows.append(
            [label] + [format_cell("{:.1f}", summary.get(key, {}).get(s, "-")) for s in sensors]
        )
    header = ["Mbit by UAV", *sensors]
    return table_html(header, rows, f"uav-sensor-table-{index}")


def uavs_section(fleets: tuple[FleetRun, ...]) -> str:
    """The per-UAV tables of every run (a heading per run in a compare report)."""
    parts = []
    for index, fleet in enumerate(fleets):
        heading = f"<h3>{html.escape(fleet.label)}</h3>" if len(fleets) > 1 else ""
        parts.append(heading + uav_table(fleet, index) + uav_sensor_table(fleet, index))
    return "".join(parts)


def build_fleet_report(folder: Path, pdf: bool = True, out: Path | None = None) -> Path:
    """Write ``report.html`` (and ``figures/*.png|pdf``) for a fleet run folder or a compare
    folder of fleet runs into ``out`` (default: ``folder``); returns the HTML path.
    ``pdf=False`` skips the PDFs."""
    kind, fleets = load_fleet_input(folder)
    runs = tuple(f.run for f in fleets)
    figures = (out or folder) / FIGURES_DIR
    first = runs[0].summary
    labels = ", ".join(f.label for f in fleets)
    title = f"{first.get('scenario', folder.name)}: {labels} ({len(fleets[0].uavs)} UAVs)"
    sections: list[tuple[str, str, str]] = [
        ("summary", "Fleet summary", fleet_table(fleets) + sensor_table(runs)),
        ("uavs", "UAVs", uavs_section(fleets)),
    ]
    if kind == "compare":
        bound = comparison_bound(read_comparison(folder / COMPARISON_FILE))
        warned = bound_warnings(folder) if bound is not None else ()
        bars = render_bars(runs, figures, pdf, bound, bound_valid=not warned)
        caption = "Data downloaded per policy (all UAVs), stacked by sensor; dashed: total buffer"
        caption += bound_caption(
            bound, warned, "the K-UAV upper bound on what any policies can download"
        )
        sections.append(
            (
                "comparison",
                "Policy comparison",
                invalid_bound_note(warned)
                + figure_html("policies", bars, caption + ".", PANEL_WIDTH_IN)
                + (gap_table(runs, bound, valid=not warned) if bound is not None else ""),
            )
        )
    for panel in FLEET_PANELS:
        png = render_fleet_panel(panel, fleets, figures, pdf)
        width = PANEL_WIDTH_IN * grid_shape(len(fleets))[1]
        sections.append((panel.key, panel.title, figure_html(panel.key, png, panel.caption, width)))
    scenario = runs[0].scenario
    text = json.dumps(scenario, indent=2) if scenario else "(no scenario.json)"
    sections.append(("scenario", "Scenario", f"<pre>{html.escape(text)}</pre>"))
    notes = sorted({note for r in runs for note in r.site.notes})
    note_html = "".join(f'<p class="note">{html.escape(n)}</p>' for n in notes)
    what = "fleet run folder" if kind == "run" else f"compare folder of {len(fleets)} fleet runs"
    intro = (
        f"<p>skymule report of <code>{html.escape(str(folder))}</code> ({what}; UAVs: "
        f"{html.escape(', '.join(fleets[0].uavs))}).</p>{note_html}"
    )
    return atomic.write_text((out or folder) / REPORT_FILE, page_html(title, intro, sections))

"""Report figures that need more than the slot table: map, remaining data, SNR, policies, score.

Each ``draw_*`` function draws on a given Axes from :class:`~skymule.report.inputs.RunData`
(files only) and returns the Axes; the cumulative-download and SNR-CDF panels live in
:mod:`skymule.report.figures`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.patches import Polygon as PolygonPatch

from skymule.report.inputs import RunData, ScoreBreakdown, hover_segments
from skymule.report.style import (
    FENCE_STYLE,
    HOME_MARKER,
    HOVER_MARKER,
    NEUTRAL,
    TOTAL_STYLE,
    TOWER_MARKER,
    label_height,
    sensor_colours,
)
from skymule.rules.defaults import AADM_WINDOW_S


def served_colours(run: RunData) -> list[str]:
    """(T,) colour of each slot: its served sensor's colour, grey when none."""
    colours = sensor_colours(run.sensor_names)
    return [colours.get(name, NEUTRAL) for name in run.slots["served"]]


def flight_map_title(run: RunData, title: str) -> str:
    """The panel title; autonomous runs add their visit order (a fixed path has none)."""
    order = run.summary.get("visit_order") or []
    if run.site.mode == "autonomous" and order:
        return f"{title}\nvisit order: {' > '.join(map(str, order))}"
    return title


def draw_flight_map(ax: Axes, run: RunData, title: str = "") -> Axes:
    """Flown path over the geofence and towers; segments coloured by served sensor.

    Hover points are circles (area grows with hover time), the home point a star. Only what
    is drawn gets a legend entry (no "hover point" without hover points).
    """
    site, slots = run.site, run.slots
    colours = sensor_colours(run.sensor_names)
    if site.fence_xy_m is not None:
        ax.add_patch(PolygonPatch(site.fence_xy_m, closed=True, label="geofence", **FENCE_STYLE))
    xy = slots[["x_m", "y_m"]].to_numpy(float)
    segment_colours = served_colours(run)[:-1]
    if len(xy) > 1:
        segments = np.stack([xy[:-1], xy[1:]], axis=1)
        ax.add_collection(LineCollection(list(segments), colors=segment_colours, lw=1.5))
    for name in run.sensor_names:  # legend proxies for the path colours actually drawn
        if colours[name] in segment_colours:
            ax.plot([], [], color=colours[name], lw=1.5, label=f"serving {name}")
    if NEUTRAL in segment_colours:
        ax.plot([], [], color=NEUTRAL, lw=1.5, label="no download")
    hovers = hover_segments(slots, run.slot_s)
    for hover in hovers:
        ax.scatter(
            hover.x_m,
            hover.y_m,
            s=12 + 1.0 * hover.duration_s,
            marker=HOVER_MARKER,
            facecolors="none",
            edgecolors=colours.get(hover.sensor, NEUTRAL),
            linewidths=1.2,
            zorder=4,
        )
    if hovers:
        ax.plot([], [], marker=HOVER_MARKER, ls="", mfc="none", mec="k", label="hover point")
    for index in site.known_sensors:
        name = site.sensor_names[index]
        x_m, y_m = site.sensor_xyz_m[index, :2]
        colour = colours.get(name, NEUTRAL)
        ax.scatter(x_m, y_m, marker=TOWER_MARKER, s=45, color=colour, ec="k", lw=0.6, zorder=5)
        ax.annotate(name, (x_m, y_m), xytext=(3, 3), textcoords="offset points", fontsize=7)
    if site.known_sensors:
        ax.plot([], [], marker=TOWER_MARKER, ls="", color="0.6", mec="k", label="tower")
    home_x, home_y = site.home_xy_m
    ax.scatter(home_x, home_y, marker=HOME_MARKER, s=70, color="k", zorder=6)
    ax.plot([], [], marker=HOME_MARKER, ls="", color="k", ms=8, label="home")
    ax.update_datalim(xy if len(xy) else np.zeros((1, 2)))
    if site.fence_xy_m is not None:
        ax.update_datalim(site.fence_xy_m)
    if site.known_sensors:
        ax.update_datalim(site.sensor_xyz_m[site.known_sensors, :2])
    ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_title(flight_map_title(run, title))
    return ax


def draw_remaining(ax: Axes, run: RunData, title: str = "") -> Axes:
    """Data left in each sensor's buffer at the end of every slot [Mbit]."""
    slots = run.slots
    colours = sensor_colours(run.sensor_names)
    end_t = slots["t_s"] + run.slot_s
    for name in run.sensor_names:
        column = f"remaining_mbit_{name}"
        if column in slots:
            ax.step(end_t, slots[column], where="post", color=colours[name], label=name)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("remaining [Mbit]")
    ax.set_title(title)
    return ax


#: Line widths of the SNR panel: thick while the sensor is served, thin otherwise.
SERVED_LW, UNSERVED_LW = 2.0, 0.6


def draw_snr_time(ax: Axes, run: RunData, title: str = "") -> Axes:
    """SNR to each sensor over time; the served sensor's line is drawn thicker, and the
    legend says so (grey "served" and "not served" entries)."""
    slots = run.slots
    colours = sensor_colours(run.sensor_names)
    for name in run.sensor_names:
        snr = slots[f"snr_db_{name}"].to_numpy(float)
        ax.plot(slots["t_s"], snr, color=colours[name], lw=UNSERVED_LW, alpha=0.6)
        ax.plot(
            slots["t_s"],
            np.where(slots["served"] == name, snr, np.nan),
            color=colours[name],
            lw=SERVED_LW,
            label=name,
        )
    ax.plot([], [], color=NEUTRAL, lw=SERVED_LW, label="served (thick)")
    ax.plot([], [], color=NEUTRAL, lw=UNSERVED_LW, label="not served (thin)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("SNR [dB]")
    ax.set_title(title)
    return ax


#: The upper bound on any policy's download: black and solid, unlike the grey dashed buffer.
BOUND_STYLE: dict[str, Any] = {"color": "black", "ls": "-", "lw": 1.0}

#: A bound whose method's condition fails for this mission (``bound.json``'s warnings): it
#: may be below what a policy can download, so it is drawn red and dotted, never solid.
INVALID_BOUND_STYLE: dict[str, Any] = {"color": "tab:red", "ls": ":", "lw": 1.2}
INVALID_BOUND_LABEL = "bound (invalid here: condition fails)"


def draw_policy_bars(
    ax: Axes,
    runs: Sequence[RunData],
    title: str = "",
    bound_mbit: float | None = None,
    bound_valid: bool = True,
) -> Axes:
    """Downloaded data per run, stacked by sensor, against the total buffer (grey dashed)
    and, when ``compare`` computed one, the upper bound on any policy (black; red and dotted,
    labelled invalid, when ``bound_valid`` is False). Each total is written above the bar, or
    above the lines when they would cross it."""
    names = list(dict.fromkeys(n for run in runs for n in run.sensor_names))
    colours = sensor_colours(names)
    positions = np.arange(len(runs))
    bottom = np.zeros(len(runs))
    for name in names:
        values = np.array(
            [float(r.summary.get("per_sensor_downloaded_mbit", {}).get(name, 0.0)) for r in runs]
        )
        ax.bar(positions, values, bottom=bottom, color=colours[name], label=name, width=0.6)
        bottom += values
    buffers = [float(r.summary.get("total_buffer_mbit", 0.0)) for r in runs]
    top = max([float(bottom.max(initial=0.0)), *buffers, bound_mbit or 0.0])
    for x_pos, height, buffer in zip(positions, bottom, buffers, strict=True):
        ax.hlines(buffer, x_pos - 0.35, x_pos + 0.35, label="total buffer", **TOTAL_STYLE)
        ax.annotate(
            f"{height:.0f}", (x_pos, label_height(height, [buffer, bound_mbit], top)),
            xytext=(0, 2), textcoords="offset points", ha="center", va="bottom", fontsize=7,
        )  # fmt: skip
    if bound_mbit is not None and bound_valid:
        ax.axhline(bound_mbit, label="upper bound", **BOUND_STYLE)
    elif bound_mbit is not None:
        ax.axhline(bound_mbit, label=INVALID_BOUND_LABEL, **INVALID_BOUND_STYLE)
    ax.set_ylim(0, 1.15 * top if top > 0 else 1.0)  # room for the value labels
    ax.set_xticks(positions, [r.label for r in runs])
    ax.set_ylabel("downloaded [Mbit]")
    ax.grid(axis="x", visible=False)
    ax.set_title(title)
    return ax


def draw_score(
    ax: Axes,
    labels: Sequence[str],
    scores: Sequence[ScoreBreakdown],
    window_s: float = AADM_WINDOW_S,
) -> Axes:
    """AADM score parts per run: S2 (download points) + S1 (time bonus) - landing penalty.

    S2 counts what was downloaded inside the ``window_s`` window, which is not the run's
    completion when the mission is longer than the window; the legend says so. The total is
    written inside the axes next to each bar's end, with head room above and below, so it
    never meets the title or the (figure) legend.
    """
    positions = np.arange(len(scores))
    download = np.array([s.download_points for s in scores])
    bonus = np.array([s.time_bonus for s in scores])
    penalty = np.array([s.landing_penalty for s in scores])
    window = f"{window_s:g} s"
    ax.bar(
        positions, download, width=0.6, color="#0072B2",
        label=f"S2: 100 × share downloaded in the first {window}",
    )  # fmt: skip
    if (bonus > 0).any():
        bonus_label = f"S1: {window} − t1 (all downloaded by t1)"
        ax.bar(positions, bonus, bottom=download, width=0.6, color="#009E73", label=bonus_label)
    if (penalty > 0).any():
        ax.bar(positions, -penalty, width=0.6, color="#D55E00", label="landing penalty")
    high = float(max((download + bonus).max(initial=0.0), 1.0))
    low = float(min((-penalty).min(initial=0.0), 0.0))
    span = high - low
    ax.set_ylim(low - (0.12 * span if low < 0 else 0.0), high + 0.12 * span)
    for x_pos, score, up in zip(positions, scores, download + bonus, strict=True):
        ax.annotate(
            f"{score.total:.1f}", (x_pos, up), xytext=(0, 2), textcoords="offset points",
            ha="center", va="bottom", fontsize=7, fontweight="bold",
        )  # fmt: skip
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xticks(positions, list(labels))
    ax.set_ylabel("AADM score (bold: total)")
    ax.grid(axis="x", visible=False)
    return ax

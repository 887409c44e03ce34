"""Report figures that need more than the slot table: map, remaining data, SNR, policies, score.

Each ``draw_*`` function draws on a given Axes from :class:`~skymule.report.inputs.RunData`
(files only) and returns the Axes; the cumulative-download and SNR-CDF panels live in
:mod:`skymule.report.figures`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.lines import Line2D
from matplotlib.patches import Polygon as PolygonPatch

from skymule.report.figures import sensor_colours
from skymule.report.inputs import RunData, ScoreBreakdown, hover_segments
from skymule.report.style import NEUTRAL


def served_colours(run: RunData) -> list[str]:
    """(T,) colour of each slot: its served sensor's colour, grey when none."""
    colours = sensor_colours(run.sensor_names)
    return [colours.get(name, NEUTRAL) for name in run.slots["served"]]


def draw_flight_map(ax: Axes, run: RunData, title: str = "") -> Axes:
    """Flown path over the geofence and towers; segments coloured by served sensor.

    Hover points are circles (area grows with hover time), the home point a star.
    """
    site, slots = run.site, run.slots
    colours = sensor_colours(run.sensor_names)
    if site.fence_xy_m is not None:
        ax.add_patch(
            PolygonPatch(site.fence_xy_m, closed=True, fc="#f2f2f2", ec="0.35", lw=1, ls="--")
        )
    xy = slots[["x_m", "y_m"]].to_numpy(float)
    if len(xy) > 1:
        segments = np.stack([xy[:-1], xy[1:]], axis=1)
        ax.add_collection(LineCollection(list(segments), colors=served_colours(run)[:-1], lw=1.8))
    for hover in hover_segments(slots, run.slot_s):
        ax.scatter(
            hover.x_m,
            hover.y_m,
            s=20 + 2.0 * hover.duration_s,
            facecolors="none",
            edgecolors=colours.get(hover.sensor, NEUTRAL),
            linewidths=1.5,
            zorder=4,
        )
    for index in site.known_sensors:
        name = site.sensor_names[index]
        x_m, y_m = site.sensor_xyz_m[index, :2]
        ax.scatter(x_m, y_m, marker="^", s=80, color=colours.get(name, NEUTRAL), ec="k", zorder=5)
        ax.annotate(name, (x_m, y_m), xytext=(4, 4), textcoords="offset points", fontsize=8)
    home_x, home_y = site.home_xy_m
    ax.scatter(home_x, home_y, marker="*", s=120, color="k", zorder=6)
    handles = [Line2D([], [], color=colours[n], lw=2, label=f"serving {n}") for n in colours]
    handles += [
        Line2D([], [], color=NEUTRAL, lw=2, label="no download"),
        Line2D([], [], marker="o", ls="", mfc="none", mec="k", label="hover point"),
        Line2D([], [], marker="^", ls="", color="k", label="tower"),
        Line2D([], [], marker="*", ls="", color="k", ms=10, label="home"),
    ]
    ax.legend(handles=handles, fontsize=7, loc="best", framealpha=0.8)
    ax.autoscale_view()
    ax.update_datalim(xy if len(xy) else np.zeros((1, 2)))
    if site.fence_xy_m is not None:
        ax.update_datalim(site.fence_xy_m)
    if site.known_sensors:
        ax.update_datalim(site.sensor_xyz_m[site.known_sensors, :2])
    ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_title(title)
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
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8)
    ax.set_title(title)
    return ax


def draw_snr_time(ax: Axes, run: RunData, title: str = "") -> Axes:
    """SNR to each sensor over time; the served sensor's line is drawn thicker."""
    slots = run.slots
    colours = sensor_colours(run.sensor_names)
    for name in run.sensor_names:
        snr = slots[f"snr_db_{name}"].to_numpy(float)
        ax.plot(slots["t_s"], snr, color=colours[name], lw=0.8, alpha=0.6, label=name)
        ax.plot(
            slots["t_s"],
            np.where(slots["served"] == name, snr, np.nan),
            color=colours[name],
            lw=2.2,
        )
    ax.set_xlabel("time [s]")
    ax.set_ylabel("SNR [dB]")
    ax.legend(fontsize=8, title="thick: served", title_fontsize=7)
    ax.set_title(title)
    return ax


def draw_policy_bars(ax: Axes, runs: Sequence[RunData], title: str = "") -> Axes:
    """Downloaded data per run, stacked by sensor, against the total buffer."""
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
    for x_pos, run, height in zip(positions, runs, bottom, strict=True):
        ax.annotate(f"{height:.0f}", (x_pos, height), ha="center", va="bottom", fontsize=8)
        buffer = float(run.summary.get("total_buffer_mbit", np.nan))
        ax.hlines(buffer, x_pos - 0.35, x_pos + 0.35, colors="k", linestyles=":")
    ax.set_xticks(positions, [r.label for r in runs])
    ax.set_ylabel("downloaded [Mbit]  (dotted: total buffer)")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(title)
    return ax


def draw_score(ax: Axes, labels: Sequence[str], scores: Sequence[ScoreBreakdown]) -> Axes:
    """AADM score parts per run: download points + time bonus - landing penalty."""
    positions = np.arange(len(scores))
    download = np.array([s.download_points for s in scores])
    bonus = np.array([s.time_bonus for s in scores])
    penalty = np.array([s.landing_penalty for s in scores])
    ax.bar(positions, download, width=0.6, color="#0072B2", label="100 x completion")
    ax.bar(positions, bonus, bottom=download, width=0.6, color="#009E73", label="time bonus")
    ax.bar(positions, -penalty, width=0.6, color="#D55E00", label="landing penalty")
    for x_pos, score in zip(positions, scores, strict=True):
        ax.annotate(f"{score.total:.1f}", (x_pos, max(score.total, 0.0)), ha="center", va="bottom")
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xticks(positions, list(labels))
    ax.set_ylabel("AADM score")
    ax.legend(fontsize=8)
    ax.set_title("AADM score breakdown")
    return ax

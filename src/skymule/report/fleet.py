"""Figures of a run of several UAVs (``docs/fleet.md``): one colour per UAV in every figure.

The trajectory map (``skymule plot`` and the fleet report), the Mbit each UAV downloaded from
each sensor and the cumulative download per UAV and in total (the fleet report). Reads the run
folder's files only (slots.csv with a ``uav`` column, summary.json, scenario.json), like every
figure.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.patches import Polygon as PolygonPatch

from skymule.io.textfiles import parse_json
from skymule.report.style import (
    DEFAULT_DPI,
    FENCE_STYLE,
    HOME_MARKER,
    NEUTRAL,
    SENSOR_PALETTE,
    TOTAL_STYLE,
    TOWER_MARKER,
    finish_figure,
    label_height,
    panel_figure,
    paper_style,
    save_figure,
    scenario_description,
)


def uav_colours(names: list[str]) -> dict[str, str]:
    """A colour per UAV, in order (Okabe-Ito first; never black or grey, the total's marks)."""
    return {name: SENSOR_PALETTE[i % len(SENSOR_PALETTE)] for i, name in enumerate(names)}


def _site_geometry(scenario: dict[str, Any]) -> dict[str, Any]:
    """Geofence ring, sensor and home positions [m] from a run's scenario.json (via geo)."""
    from skymule.errors import SkymuleError
    from skymule.geo import LocalFrame, load_geofence

    site = scenario.get("site", {})
    origin = site.get("origin", {"lat": 35.7274824, "lon": -78.6962749})
    frame = LocalFrame(float(origin["lat"]), float(origin["lon"]))
    fence = None
    if site.get("geofence"):
        try:
            polygon = load_geofence(site["geofence"], frame, Path(scenario.get("base_dir", ".")))
            fence = np.asarray(polygon.exterior.coords)[:, :2]
        except SkymuleError:
            fence = None  # a relative fence file that did not travel with the run folder
    sensors: dict[str, tuple[float, float]] = {}
    for sensor in scenario.get("sensors", []):
        if sensor.get("lat") is not None and sensor.get("lon") is not None:
            x_m, y_m = frame.to_local(sensor["lat"], sensor["lon"])
            sensors[sensor["name"]] = (float(x_m), float(y_m))
        elif sensor.get("x_m") is not None and sensor.get("y_m") is not None:
            sensors[sensor["name"]] = (float(sensor["x_m"]), float(sensor["y_m"]))
    home = scenario.get("trajectory", {}).get("home")
    if isinstance(home, dict):
        x_m, y_m = frame.to_local(home["lat"], home["lon"])
        home_m = (float(x_m), float(y_m))
    elif isinstance(home, list) and len(home) == 2:
        home_m = (float(home[0]), float(home[1]))
    else:
        home_m = (0.0, 0.0)
    return {"fence": fence, "sensors": sensors, "home": home_m}


def _xy(point: Any, frame: Any) -> tuple[float, float] | None:
    """A scenario point (lat/lon table or [x, y] metres) in local metres, or None."""
    if isinstance(point, dict):
        x_m, y_m = frame.to_local(point["lat"], point["lon"])
        return (float(x_m), float(y_m))
    if isinstance(point, list) and len(point) == 2:
        return (float(point[0]), float(point[1]))
    return None


def draw_fleet_trajectory(
    ax: Axes,
    slots: pd.DataFrame,
    summary: dict[str, Any],
    scenario_json: dict[str, Any],
    *,
    legend: bool = True,
    title: str | None = None,
    marker_scale: float = 1.0,
) -> Axes:
    """Several UAVs (slots.csv with a ``uav`` column): one colour per UAV, its home a star.

    Geofence and towers as :func:`draw_trajectory`; thick where the UAV served a sensor, thin
    where it served none; crosses where it lost a sensor to another UAV. ``legend=False``
    leaves the legend to the figure (the report draws one below its panels); ``title``
    replaces the default "scenario - policy"; ``marker_scale`` scales the marker areas (the
    report's 3.5-inch panels use smaller marks than ``plot``'s 6.5-inch figure).
    """
    from skymule.geo import LocalFrame

    geometry = _site_geometry(scenario_json)
    origin = scenario_json.get("site", {}).get("origin", {"lat": 35.7274824, "lon": -78.6962749})
    frame = LocalFrame(float(origin["lat"]), float(origin["lon"]))
    if geometry["fence"] is not None:  # as the one-UAV map draws it (FENCE_STYLE)
        patch = PolygonPatch(geometry["fence"], closed=True, label="geofence", **FENCE_STYLE)
        ax.add_patch(patch)
        ax.update_datalim(geometry["fence"])
    homes = {u["name"]: _xy(u.get("home"), frame) for u in scenario_json.get("uavs") or []}
    uavs = list(dict.fromkeys(slots["uav"].astype(str)))
    colours = uav_colours(uavs)
    for name in uavs:
        rows = slots[slots["uav"].astype(str) == name]
        colour = colours[name]
        ax.plot(rows["x_m"], rows["y_m"], color=colour, lw=0.8, alpha=0.6)
        serving = rows["served"] != ""
        ax.scatter(
            rows["x_m"][serving], rows["y_m"][serving], s=6 * marker_scale, color=colour, label=name
        )
        if "lost" in rows:
            lost = rows[rows["lost"] == 1]
            ax.scatter(
                lost["x_m"], lost["y_m"], marker="x", s=20 * marker_scale, color=colour, zorder=5
            )
        home = homes.get(name) or geometry["home"]
        ax.scatter(
            [home[0]], [home[1]], marker=HOME_MARKER, s=70 * marker_scale, color=colour,
            edgecolor="black", lw=0.6, zorder=6,
        )  # fmt: skip
    for sensor, (x_m, y_m) in geometry["sensors"].items():
        ax.scatter(
            [x_m], [y_m], marker=TOWER_MARKER, s=45 * marker_scale, color=NEUTRAL,
            edgecolor="black", lw=0.6, zorder=4,
        )  # fmt: skip
        ax.annotate(sensor, (x_m, y_m), textcoords="offset points", xytext=(3, 3), fontsize=7)
    if geometry["sensors"]:
        ax.plot([], [], marker=TOWER_MARKER, ls="", color=NEUTRAL, mec="k", label="tower")
    ax.plot([], [], marker=HOME_MARKER, ls="", color=NEUTRAL, mec="k", ms=8, label="home")
    ax.scatter([], [], marker="x", color="0.3", label="lost to another UAV")
    default = f"{summary.get('scenario', '')} - {summary.get('policy', '')}"
    ax.set_title(default if title is None else title)
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.1)  # room for the tower names at the edges
    ax.autoscale_view()
    if legend:
        ax.legend(loc="best")
    return ax


def plot_fleet_run(
    run_dir: Path,
    summary: dict[str, Any],
    slots: pd.DataFrame,
    *,
    formats: tuple[str, ...] = ("png",),
    dpi: int = DEFAULT_DPI,
) -> list[Path]:
    """The trajectory figure of a fleet run (one colour per UAV), in the style and print size
    of every other figure (one 3.5-in panel, legend below, the scenario in words above)."""

    scenario_file = run_dir / "scenario.json"
    scenario_json = parse_json(scenario_file.read_text()) if scenario_file.is_file() else {}
    with paper_style():
        fig, (ax,) = panel_figure(1, 4.2)
        label = str(summary.get("policy", ""))
        draw_fleet_trajectory(
            ax, slots, summary, scenario_json, legend=False, title=label, marker_scale=0.6
        )
        n_uavs = slots["uav"].nunique()
        title = f"{n_uavs} UAVs: {scenario_description(scenario_json, summary)}"
        finish_figure(fig, title)
        return list(save_figure(fig, run_dir, "trajectory", formats, dpi).values())


def draw_uav_sensor_bars(
    ax: Axes,
    by_uav: pd.DataFrame,
    buffers_mbit: dict[str, float],
    title: str = "",
) -> Axes:
    """Mbit downloaded from each sensor, one bar per sensor stacked by UAV (UAV colours);
    a grey dash marks the sensor's buffer, the number on top is the bar's total.

    ``by_uav`` is UAVs x sensors [Mbit] (:meth:`skymule.report.fleet_inputs.FleetRun.sensor_mbit`).
    """
    sensors = [str(s) for s in by_uav.columns]
    colours = uav_colours([str(u) for u in by_uav.index])
    positions = np.arange(len(sensors))
    bottom = np.zeros(len(sensors))
    for uav, values in by_uav.iterrows():
        heights = values.to_numpy(float)
        ax.bar(positions, heights, bottom=bottom, width=0.6, color=colours[str(uav)], label=uav)
        bottom += heights
    buffers = np.array([float(buffers_mbit.get(s, np.nan)) for s in sensors])
    top = float(np.nanmax([*bottom, *buffers, 0.0]))
    for x_pos, height, buffer in zip(positions, bottom, buffers, strict=True):
        ax.annotate(  # above the buffer's dash when the bar (nearly) reaches it
            f"{height:.0f}", (x_pos, label_height(height, [buffer], top)), xytext=(0, 2),
            textcoords="offset points", ha="center", va="bottom", fontsize=7,
        )  # fmt: skip
        if np.isfinite(buffer):
            ax.hlines(buffer, x_pos - 0.35, x_pos + 0.35, label="buffer", **TOTAL_STYLE)
    ax.set_ylim(0, 1.12 * top if top > 0 else 1.0)  # room for the value labels
    ax.set_xticks(positions, sensors)
    ax.set_xlabel("sensor")
    ax.set_ylabel("downloaded [Mbit]")
    ax.grid(axis="x", visible=False)
    ax.set_title(title)
    return ax


def draw_uav_cumulative(
    ax: Axes, slots: pd.DataFrame, uavs: list[str], slot_s: float, title: str = ""
) -> Axes:
    """Data downloaded by the end of every slot, per UAV (its colour) and by the whole fleet
    (grey dashed); ``slots`` is a fleet slots.csv (``uav`` column)."""
    colours = uav_colours(uavs)
    total: np.ndarray | None = None
    end_t = np.zeros(0)
    for uav in uavs:
        rows = slots[slots["uav"] == uav]
        end_t = rows["t_s"].to_numpy(float) + slot_s
        cumulative = np.cumsum(rows["downloaded_mbit"].to_numpy(float))
        ax.plot(end_t, cumulative, color=colours[uav], label=uav)
        total = cumulative if total is None else total + cumulative  # same slots for every UAV
    if total is not None:
        ax.plot(end_t, total, label="fleet total", **TOTAL_STYLE)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("downloaded [Mbit]")
    ax.set_ylim(bottom=0)
    ax.set_title(title)
    return ax

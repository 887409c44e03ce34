"""Figures of a run of several UAVs (``docs/fleet.md``): one colour per UAV in every figure.

The trajectory map (``skymule plot`` and the fleet report), the Mbit each UAV downloaded from
each sensor and the cumulative download per UAV and in total (the fleet report). Reads the run
folder's files only (slots.csv with a ``uav`` column, summary.json, scenario.json), like every
figure.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from skymule.io import atomic
from skymule.report.style import SENSOR_PALETTE, TOTAL_STYLE


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


def _save(fig: Figure, path: Path) -> Path:
    fig.tight_layout()
    try:
        return atomic.write_with(path, lambda tmp: fig.savefig(tmp, dpi=150, format="png"))
    finally:
        plt.close(fig)


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
    if geometry["fence"] is not None:
        fence = geometry["fence"]
        ax.fill(fence[:, 0], fence[:, 1], color="#F0E442", alpha=0.15, lw=0)
        ax.plot(fence[:, 0], fence[:, 1], color="#B8A800", lw=1.2, label="geofence")
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
            [home[0]],
            [home[1]],
            marker="*",
            s=200 * marker_scale,
            color=colour,
            edgecolor="black",
            zorder=6,
        )
    for sensor, (x_m, y_m) in geometry["sensors"].items():
        ax.scatter(
            [x_m], [y_m], marker="^", s=90 * marker_scale, color="0.5", edgecolor="black", zorder=4
        )
        ax.annotate(sensor, (x_m, y_m), textcoords="offset points", xytext=(5, 5), fontsize=8)
    ax.scatter([], [], marker="*", color="0.5", edgecolor="black", label="home")
    ax.scatter([], [], marker="x", color="0.3", label="lost to another UAV")
    default = f"{summary.get('scenario', '')} - {summary.get('policy', '')}"
    ax.set_title(default if title is None else title, fontsize=9)
    ax.set_xlabel("x east [m]")
    ax.set_ylabel("y north [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.1)  # room for the tower names at the edges
    ax.autoscale_view()
    if legend:
        ax.legend(fontsize=7, loc="best")
    ax.grid(alpha=0.3)
    return ax


def plot_fleet_run(run_dir: Path, summary: dict[str, Any], slots: pd.DataFrame) -> list[Path]:
    """The trajectory figure of a fleet run (one colour per UAV); returns the paths."""
    import json

    scenario_file = run_dir / "scenario.json"
    scenario_json = json.loads(scenario_file.read_text()) if scenario_file.is_file() else {}
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    draw_fleet_trajectory(ax, slots, summary, scenario_json)
    return [_save(fig, run_dir / "trajectory.png")]


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
        near = np.isfinite(buffer) and 0.0 <= buffer - height < 0.06 * top
        ax.annotate(  # above the buffer's dash when the bar (nearly) reaches it
            f"{height:.0f}", (x_pos, buffer if near else height), xytext=(0, 2),
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

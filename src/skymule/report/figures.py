"""Figures drawn from run folders (never from a simulation): ``skymule plot``.

The draw functions take what :func:`skymule.io.runs.read_run` returns and a matplotlib Axes;
nothing here imports the engine. ``plot`` draws with the report's own panels, sizes and style
(:mod:`skymule.report.style`, :data:`skymule.report.html.PER_RUN_PANELS`), so a figure looks
the same from either command.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.axes import Axes

from skymule.io.runs import sensor_names_of
from skymule.report.style import (
    DISTANCE_STYLE,
    OKABE_ITO,
    TOTAL_STYLE,
    sensor_colours,
)

__all__ = [
    "OKABE_ITO",
    "cumulative_download_mbit",
    "draw_cumulative_download",
    "draw_snr_cdf",
    "sensor_colours",
]


def cumulative_download_mbit(slots: pd.DataFrame, name: str) -> np.ndarray:
    """(T,) cumulative Mbit downloaded from ``name`` by the end of each slot."""
    return np.cumsum(np.where(slots["served"] == name, slots["downloaded_mbit"], 0.0))


def draw_cumulative_download(ax: Axes, slots: pd.DataFrame, title: str = "") -> Axes:
    """Cumulative download per sensor and in total over time; distance flown (black dotted)
    on a second axis. Artists carry legend labels; the figure draws one legend for all."""
    names = sensor_names_of(slots)
    colours = sensor_colours(names)
    end_t = slots["t_s"] + float(slots["t_s"].diff().median() if len(slots) > 1 else 1.0)
    for name in names:
        ax.plot(end_t, cumulative_download_mbit(slots, name), color=colours[name], label=name)
    ax.plot(end_t, np.cumsum(slots["downloaded_mbit"]), label="total", **TOTAL_STYLE)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("downloaded [Mbit]")
    twin = ax.twinx()
    twin.plot(end_t, slots["distance_m"], label="distance flown", **DISTANCE_STYLE)
    twin.set_ylabel("distance flown [m]")
    twin.set_ylim(bottom=0)
    twin.grid(False)
    ax.set_title(title)
    return ax


def draw_snr_cdf(ax: Axes, slots: pd.DataFrame, title: str = "") -> Axes:
    """Empirical CDF of the SNR observed to each sensor (missing samples left out)."""
    names = sensor_names_of(slots)
    colours = sensor_colours(names)
    for name in names:
        values = np.sort(slots[f"snr_db_{name}"].dropna().to_numpy(float))
        values = values[np.isfinite(values)]
        if values.size:
            ax.step(
                values,
                np.arange(1, values.size + 1) / values.size,
                where="post",
                color=colours[name],
                label=name,
            )
    ax.set_xlabel("SNR [dB]")
    ax.set_ylabel("empirical CDF")
    ax.set_ylim(0, 1)
    ax.set_title(title)
    return ax


#: ``skymule plot``'s files: report panel key -> file stem next to the run's files.

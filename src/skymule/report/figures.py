"""Figures drawn from run folders (never from a simulation).

Every function takes what :func:`skymule.runio.read_run` returns and a matplotlib Axes or
output path; nothing here imports the engine. Colours come from the Okabe-Ito palette, which
stays distinguishable for colour-blind readers.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from skymule.runio import sensor_names_of

#: Okabe & Ito (2008) colour-blind-safe palette.
OKABE_ITO = ("#0072B2", "#E69F00", "#009E73", "#D55E00", "#CC79A7", "#56B4E9", "#F0E442", "#000000")


def sensor_colours(names: list[str]) -> dict[str, str]:
    return {name: OKABE_ITO[i % len(OKABE_ITO)] for i, name in enumerate(names)}


def cumulative_download_mbit(slots: pd.DataFrame, name: str) -> np.ndarray:
    """(T,) cumulative Mbit downloaded from ``name`` by the end of each slot."""
    return np.cumsum(np.where(slots["served"] == name, slots["downloaded_mbit"], 0.0))


def draw_cumulative_download(ax: Axes, slots: pd.DataFrame, title: str = "") -> Axes:
    """Cumulative download per sensor over time, distance flown on a second axis."""
    names = sensor_names_of(slots)
    colours = sensor_colours(names)
    end_t = slots["t_s"] + float(slots["t_s"].diff().median() if len(slots) > 1 else 1.0)
    for name in names:
        ax.plot(end_t, cumulative_download_mbit(slots, name), color=colours[name], label=name)
    ax.plot(end_t, np.cumsum(slots["downloaded_mbit"]), color="0.3", ls="--", label="total")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("downloaded [Mbit]")
    twin = ax.twinx()
    twin.plot(end_t, slots["distance_m"], color="#8B4513", lw=1.2, label="distance")
    twin.set_ylabel("distance flown [m]", color="#8B4513")
    lines = ax.get_lines() + twin.get_lines()
    ax.legend(lines, [ln.get_label() for ln in lines], loc="upper left", fontsize=8)
    ax.set_title(title)
    ax.grid(alpha=0.3)
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
    ax.set_ylabel("CDF")
    ax.set_ylim(0, 1)
    ax.legend(fontsize=8)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    return ax


def _save(fig: Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path


def plot_run(run_dir: Path, summary: dict[str, Any], slots: pd.DataFrame) -> list[Path]:
    """Write the run's standard figures as PNG next to its files; returns the paths."""
    title = f"{summary.get('scenario', '')} - {summary.get('policy', '')}"
    fig, ax = plt.subplots(figsize=(7, 4))
    draw_cumulative_download(ax, slots, title)
    download = _save(fig, run_dir / "download.png")
    fig, ax = plt.subplots(figsize=(6, 4))
    draw_snr_cdf(ax, slots, title)
    cdf = _save(fig, run_dir / "snr_cdf.png")
    return [download, cdf]

"""Channel figures drawn from run folders: SNR CDF per signal source (paper Fig. 4 style)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import pandas as pd

from skymule.report.figures import draw_snr_cdf


def plot_snr_cdf_by_source(
    panels: list[tuple[str, pd.DataFrame]], out_path: Path, title: str = ""
) -> Path:
    """One panel per source (title, slots frame), one CDF curve per sensor; PNG at out_path."""
    fig, axes = plt.subplots(
        1, len(panels), figsize=(4.2 * len(panels), 3.6), sharey=True, squeeze=False
    )
    for ax, (label, slots) in zip(axes[0], panels, strict=True):
        draw_snr_cdf(ax, slots, title=label)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out_path, dpi=150)
    plt.close(fig)
    return out_path

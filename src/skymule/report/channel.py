"""Channel figures drawn from run folders: SNR CDF per signal source (paper Fig. 4 style)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from skymule.report.figures import draw_snr_cdf
from skymule.report.style import (
    DEFAULT_DPI,
    finish_figure,
    label_outer_panels,
    panel_figure,
    paper_style,
    save_figure,
)


def plot_snr_cdf_by_source(
    panels: list[tuple[str, pd.DataFrame]],
    out_path: Path,
    title: str = "",
    *,
    formats: tuple[str, ...] | None = None,
    dpi: int = DEFAULT_DPI,
) -> Path:
    """One print-sized panel per source (title, slots frame), two a row, one CDF curve per
    sensor, all panels on the same SNR range; writes ``out_path`` (and the other ``formats``
    next to it)."""
    with paper_style():
        fig, axes = panel_figure(len(panels), 2.6, sharex=True, sharey=True)
        for ax, (label, slots) in zip(axes, panels, strict=True):
            draw_snr_cdf(ax, slots, title=label)
        label_outer_panels(axes)  # one y label per row, one x label per column
        finish_figure(fig, title)
        fmt = out_path.suffix.lstrip(".") or "png"
        written = save_figure(fig, out_path.parent, out_path.stem, formats or (fmt,), dpi)
    return written[fmt] if fmt in written else next(iter(written.values()))

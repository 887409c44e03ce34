"""The degradation figure of ``skymule resilience``: Mbit against fault intensity, per policy.

Drawn from the study's table (``resilience.csv``'s frame), in the house style: one 3.5-in
panel, each policy its colour, marker and line style (so two policies on top of each other
both show), 95 % confidence intervals as error bars offset a little per policy (bands of
several policies would cover each other), the fault-free bound dashed, the legend below and
the scenario in words as the title.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.report.style import (
    DEFAULT_DPI,
    finish_figure,
    panel_figure,
    paper_style,
    policy_styles,
    save_figure,
)

#: The fault-free bound: black dashed (the policies are solid, dashed-dotted, dotted).
BOUND_STYLE: dict[str, Any] = {"color": "black", "ls": (0, (5, 3)), "lw": 0.9}


def plot_resilience(
    frame: pd.DataFrame, axis_label: str, path: Path, title: str = "", dpi: int = DEFAULT_DPI
) -> Path:
    """Write the figure to ``path`` (its suffix is the format); returns the path.

    ``frame`` has one row per policy and level (``policy``, ``level``, ``mbit_mean``,
    ``mbit_ci95``, ``bound_mbit_mean``); ``axis_label`` says what a level is, in words with
    its unit.
    """
    policies = list(dict.fromkeys(frame["policy"].astype(str)))
    styles = policy_styles(policies)
    levels = np.sort(frame["level"].unique().astype(float))
    step = float(np.min(np.diff(levels))) if levels.size > 1 else 1.0
    with paper_style():
        fig, (ax,) = panel_figure(1, 2.6)
        for rank, policy in enumerate(policies):
            rows = frame[frame["policy"].astype(str) == policy].sort_values("level")
            dodge = (rank - (len(policies) - 1) / 2) * 0.06 * step
            ax.errorbar(
                rows["level"].to_numpy(float) + dodge,
                rows["mbit_mean"].to_numpy(float),
                yerr=rows["mbit_ci95"].to_numpy(float),
                capsize=2,
                ms=4,
                mfc="white",
                label=policy,
                **styles[policy],
            )
        bound = frame["bound_mbit_mean"].dropna()
        if not bound.empty:
            ax.axhline(float(bound.iloc[0]), label="bound (fault-free)", **BOUND_STYLE)
        ax.set_xlabel(textwrap.fill(axis_label, 45))  # the axes width at 8 pt
        ax.set_ylabel("downloaded [Mbit]\n(mean, 95 % CI)")
        finish_figure(fig, title)
        fmt = path.suffix.lstrip(".") or "png"
        return save_figure(fig, path.parent, path.stem, (fmt,), dpi)[fmt]

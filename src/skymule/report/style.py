"""One look for every report figure: paper-sized, colour-blind-safe, vector PDF + PNG.

Colours per sensor come from :func:`skymule.report.figures.sensor_colours` (Okabe-Ito), so
a tower has the same colour in every figure of every report.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
from cycler import cycler
from matplotlib.figure import Figure

from skymule.report.figures import OKABE_ITO

if TYPE_CHECKING:
    from matplotlib.typing import RcKeyType

#: Colour of "no sensor served" path segments and of neutral marks.
NEUTRAL = "#999999"

PAPER_RC: dict[RcKeyType, Any] = {
    "font.size": 9,
    "axes.titlesize": 10,
    "axes.labelsize": 9,
    "legend.fontsize": 8,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "axes.prop_cycle": cycler(color=list(OKABE_ITO)),
    "axes.spines.top": False,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "lines.linewidth": 1.4,
    "savefig.bbox": "tight",
    "pdf.fonttype": 42,  # TrueType in the PDF: editable text, accepted by publishers
    "ps.fonttype": 42,
    "svg.fonttype": "none",
    "figure.dpi": 100,
}


@contextmanager
def paper_style() -> Iterator[None]:
    """Apply the report style for the duration of a ``with`` block (no global change)."""
    with plt.rc_context(PAPER_RC):
        yield


def save_figure(
    fig: Figure, folder: Path, stem: str, dpi: int = 150, pdf: bool = True
) -> tuple[Path, Path | None]:
    """Write ``folder/stem.png`` and (unless ``pdf=False``) the vector ``folder/stem.pdf``.

    Closes the figure.
    """
    folder.mkdir(parents=True, exist_ok=True)
    png = folder / f"{stem}.png"
    fig.savefig(png, dpi=dpi)
    vector = folder / f"{stem}.pdf" if pdf else None
    if vector is not None:
        fig.savefig(vector)
    plt.close(fig)
    return png, vector

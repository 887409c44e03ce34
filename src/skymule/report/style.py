"""One look for every figure of ``skymule plot`` and ``skymule report``: print-sized panels,
colour-blind-safe colours, the same marks and labels everywhere, PNG/PDF/SVG output.

* Size: a panel is ``PANEL_WIDTH_IN`` (3.5 in, one column of a two-column paper) wide and is
  drawn at that size, so 8-9 pt text prints at 8-9 pt; runs of a compare folder sit side by
  side, one panel each.
* Colours: a sensor keeps its colour in every figure (:func:`sensor_colours`): Okabe & Ito's
  palette without its black, then Tol's "muted" palette, 16 distinct colours; beyond 16 the
  colours are spread over a perceptual colour map. Black and grey are never a sensor's: black
  dotted is the distance flown, grey dashed the total, grey "no sensor served".
* Legends go below the panels, once per figure (:func:`finish_figure`), never over the data;
  the figure's title is the scenario in words (:func:`scenario_description`), not its id.
"""

from __future__ import annotations

import textwrap
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib
import numpy as np

matplotlib.use("Agg")

import matplotlib.pyplot as plt
from cycler import cycler
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from skymule.errors import SkymuleError
from skymule.io import atomic

if TYPE_CHECKING:
    from matplotlib.typing import RcKeyType

#: Okabe & Ito (2008) colour-blind-safe palette (its black last).
OKABE_ITO = ("#0072B2", "#E69F00", "#009E73", "#D55E00", "#CC79A7", "#56B4E9", "#F0E442", "#000000")
#: Paul Tol's "muted" qualitative palette (colour-blind safe), after Okabe-Ito's colours.
TOL_MUTED = (
    "#332288",
    "#88CCEE",
    "#44AA99",
    "#117733",
    "#999933",
    "#DDCC77",
    "#CC6677",
    "#882255",
    "#AA4499",
)
#: Sensor colours in order: never black or grey (those are the distance, total and idle marks).
SENSOR_PALETTE = OKABE_ITO[:-1] + TOL_MUTED

#: Colour of "no sensor served" path segments and of neutral marks.
NEUTRAL = "#999999"
#: The distance flown: black and dotted, unlike any sensor.
DISTANCE_STYLE: dict[str, Any] = {"color": "black", "ls": ":", "lw": 1.4}
#: The total over sensors: grey and dashed.
TOTAL_STYLE: dict[str, Any] = {"color": "0.35", "ls": "--", "lw": 1.2}
#: Markers shared by the static map (plot and report) and the interactive view.
TOWER_MARKER = "^"
HOME_MARKER = "*"
HOVER_MARKER = "o"
FENCE_STYLE: dict[str, Any] = {"fc": "#f2f2f2", "ec": "0.35", "lw": 1.0, "ls": "--"}

#: Width of one panel [in]: a column of a two-column paper.
PANEL_WIDTH_IN = 3.5
#: Resolution of raster output [dots per inch] (journals ask for >= 300).
DEFAULT_DPI = 300
#: Formats figures can be written in.
FIGURE_FORMATS = ("png", "pdf", "svg")

#: Words for axis labels, from scenario keys (units in brackets).
PARAMETER_WORDS = {
    "buffer_mbit": "buffer [Mbit]",
    "duration_s": "mission duration [s]",
    "slot_s": "slot length [s]",
    "speed_mps": "speed [m/s]",
    "max_speed_mps": "maximum speed [m/s]",
    "altitude_m": "altitude [m]",
    "height_m": "antenna height [m]",
    "x_m": "east position [m]",
    "y_m": "north position [m]",
    "hover_threshold": "hover threshold [fraction of peak rate]",
    "max_hover_s": "maximum hover time [s]",
    "tx_power_dbm": "transmit power [dBm]",
    "noise_dbm": "noise power [dBm]",
    "frequency_hz": "carrier frequency [Hz]",
    "bandwidth_hz": "bandwidth [Hz]",
    "shadowing_std_db": "shadowing std. dev. [dB]",
    "shadowing_decorrelation_m": "shadowing decorrelation distance [m]",
    "rician_k_db": "Rician K factor [dB]",
    "visit_radius_m": "visit radius [m]",
}
_UNITS = {"mbit": "Mbit", "s": "s", "m": "m", "mps": "m/s", "db": "dB", "dbm": "dBm", "hz": "Hz"}
_MODELS = {"fspl": "free space", "log-distance": "log-distance path loss", "two-ray": "two-ray"}

PAPER_RC: dict[RcKeyType, Any] = {
    "font.size": 8,
    "axes.titlesize": 8,
    "axes.labelsize": 8,
    "legend.fontsize": 7,
    "xtick.labelsize": 7,
    "ytick.labelsize": 7,
    "figure.titlesize": 9,
    "axes.prop_cycle": cycler(color=list(SENSOR_PALETTE)),
    "axes.spines.top": False,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "lines.linewidth": 1.2,
    "legend.frameon": False,
    "legend.handlelength": 1.6,
    "legend.columnspacing": 1.0,
    "pdf.fonttype": 42,  # TrueType in the PDF: editable text, accepted by publishers
    "ps.fonttype": 42,
    "svg.fonttype": "none",
    "svg.hashsalt": "skymule",  # identical SVGs for identical figures
    "figure.dpi": 100,
}


@contextmanager
def paper_style() -> Iterator[None]:
    """Apply the figure style for the duration of a ``with`` block (no global change)."""
    with plt.rc_context(PAPER_RC):
        yield


def sensor_colours(names: Sequence[str]) -> dict[str, str]:
    """A distinct colour per sensor, in order; the same names get the same colours."""
    if len(names) <= len(SENSOR_PALETTE):
        return {name: SENSOR_PALETTE[i] for i, name in enumerate(names)}
    cmap = matplotlib.colormaps["turbo"]
    step = 0.9 / (len(names) - 1)
    return {name: matplotlib.colors.to_hex(cmap(0.05 + i * step)) for i, name in enumerate(names)}


#: Markers and line styles that tell policies apart where their lines overlap (with colour).
POLICY_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "h")
POLICY_LINES: tuple[Any, ...] = ("-", "--", "-.", ":")


def policy_styles(names: Sequence[str]) -> dict[str, dict[str, Any]]:
    """A colour (the sensor palette's order), marker and line style per policy, in order:
    two policies with the same results still show as two marks."""
    colours = sensor_colours(names)
    return {
        name: {
            "color": colours[name],
            "marker": POLICY_MARKERS[i % len(POLICY_MARKERS)],
            "ls": POLICY_LINES[i % len(POLICY_LINES)],
        }
        for i, name in enumerate(names)
    }


def report_formats(pdf: bool) -> tuple[str, ...]:
    """The formats a report writes each figure in: PNG (embedded), and PDF (vector) unless
    ``pdf`` is False."""
    return ("png", "pdf") if pdf else ("png",)


def parse_formats(text: str) -> tuple[str, ...]:
    """``"png,pdf,svg"`` -> ``("png", "pdf", "svg")``; a one-line error for anything else."""
    formats = tuple(dict.fromkeys(f.strip().lower().lstrip(".") for f in text.split(",")))
    bad = [f for f in formats if f not in FIGURE_FORMATS]
    if not formats or bad or "" in formats:
        raise SkymuleError(
            f"--format {text!r}: {', '.join(repr(b) for b in bad) or 'empty'} is not a figure "
            f"format; allowed: a comma-separated list of {', '.join(FIGURE_FORMATS)}"
        )
    return formats


def check_dpi(dpi: int) -> int:
    """The raster resolution, if sensible (one-line error otherwise)."""
    if not 50 <= dpi <= 2400:
        raise SkymuleError(f"--dpi {dpi}: allowed: 50 to 2400 dots per inch")
    return dpi


def parameter_label(key: str) -> str:
    """Words and unit for a dotted scenario key: ``sensors[*].buffer_mbit`` -> ``buffer [Mbit]``.

    Known fields come from ``PARAMETER_WORDS``; others are read off their name (``_s`` ->
    ``[s]``, ``_mbit`` -> ``[Mbit]``...), underscores turned into spaces.
    """
    field = key.rsplit(".", 1)[-1]
    if field in PARAMETER_WORDS:
        return PARAMETER_WORDS[field]
    words = field.split("_")
    unit = _UNITS.get(words[-1]) if len(words) > 1 else None
    text = " ".join(words[:-1] if unit else words)
    return f"{text} [{unit}]" if unit else text


def scenario_description(scenario: dict[str, Any], summary: dict[str, Any]) -> str:
    """The scenario in words, for figure titles: its ``description`` when it has one, else
    what it is (sensors, path, channel, length), never its id."""
    text = scenario.get("description")
    if isinstance(text, str) and text.strip():
        return text.strip()
    n_sensors = len(scenario.get("sensors", [])) or len(summary.get("per_sensor_buffer_mbit", {}))
    signal = scenario.get("signal", {}).get("source", "model")
    mode = scenario.get("trajectory", {}).get("mode", "fixed")
    parts = [f"{n_sensors} sensor{'s' if n_sensors != 1 else ''}"]
    if signal == "trace":
        parts.append("recorded flight")
    else:
        parts.append("autonomous flight" if mode == "autonomous" else "fixed path")
        model = str(scenario.get("radio", {}).get("model", "fspl"))
        parts.append("radio map" if signal == "radiomap" else _MODELS.get(model, model))
    seconds = summary.get("mission_time_s")
    if isinstance(seconds, int | float):
        parts.append(f"{seconds:.0f} s")
    return ", ".join(parts)


#: Panels a figure puts side by side at most: two make 7 in, the full text width of a
#: two-column paper (IEEE: 7.16 in); more runs wrap into further rows.
MAX_COLUMNS = 2


def grid_shape(n_panels: int, max_columns: int = MAX_COLUMNS) -> tuple[int, int]:
    """(rows, columns) of a figure of ``n_panels`` print-sized panels."""
    columns = max(1, min(n_panels, max_columns))
    return -(-n_panels // columns), columns


def panel_figure(
    n_panels: int,
    height_in: float,
    *,
    sharex: bool = False,
    sharey: bool = False,
    max_columns: int = MAX_COLUMNS,
) -> tuple[Figure, list[Axes]]:
    """A figure of ``n_panels`` print-sized panels (constrained layout), at most
    ``max_columns`` side by side and as many rows as it takes; returns the panels in reading
    order (a last row that is not full leaves its empty places blank)."""
    rows, columns = grid_shape(n_panels, max_columns)
    fig, grid = plt.subplots(
        rows,
        columns,
        figsize=(PANEL_WIDTH_IN * columns, height_in * rows),
        squeeze=False,
        sharex=sharex,
        sharey=sharey,
        layout="constrained",
    )
    axes = list(grid.ravel())
    for spare in axes[n_panels:]:
        spare.remove()
    return fig, axes[:n_panels]


def label_outer_panels(axes: Sequence[Axes], max_columns: int = MAX_COLUMNS) -> None:
    """For panels on one scale (shared axes): the y label on the first column only, the x
    label on the lowest panel of each column only (the figure reads as one plot)."""
    _, columns = grid_shape(len(axes), max_columns)
    for index, ax in enumerate(axes):
        if index % columns:
            ax.set_ylabel("")
        if index + columns < len(axes):
            ax.set_xlabel("")
            ax.tick_params(labelbottom=False)
        else:  # the lowest of its column, though not on the last row: its ticks read
            ax.tick_params(labelbottom=True)


def _legend_entries(fig: Figure) -> tuple[list[Artist], list[str]]:
    """Labelled artists of every axes (twins included), each label once, in drawing order."""
    handles: list[Artist] = []
    labels: list[str] = []
    for ax in fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            if label not in labels and not label.startswith("_"):
                handles.append(handle)
                labels.append(label)
    return handles, labels


def finish_figure(fig: Figure, title: str = "", columns: int | None = None) -> None:
    """One legend below all panels (every labelled artist once), the title above them."""
    handles, labels = _legend_entries(fig)
    if handles:
        longest = max(len(label) for label in labels)
        fits = int(fig.get_figwidth() / (0.35 + 0.06 * longest))  # entries a row holds
        ncol = columns or max(1, min(len(labels), fits))
        fig.legend(handles, labels, loc="outside lower center", ncol=ncol)
    if title:
        fig.suptitle(wrap_title(title, fig.get_figwidth()))


def label_height(height: float, lines: Sequence[float | None], top: float) -> float:
    """Where a bar's value label goes: on the bar, or on the highest of ``lines`` (a buffer,
    a bound) that runs just above it, so the number never sits on a line. A 7-pt label on a
    ~2-in axes spans ~10 % of its height (``top``: the largest value drawn)."""
    near = [v for v in lines if v is not None and np.isfinite(v) and 0 <= v - height < 0.1 * top]
    return max([height, *near])


def wrap_title(title: str, width_in: float) -> str:
    """``title`` folded into lines that fit ``width_in`` at the figure-title size (a long
    scenario description would be cut at both sides of a one-panel figure)."""
    size = float(PAPER_RC["figure.titlesize"])
    per_line = max(20, int(width_in * 72 / (0.55 * size)))  # ~0.55 em a character
    return "\n".join(textwrap.wrap(title, per_line)) or title


def save_figure(
    fig: Figure,
    folder: Path,
    stem: str,
    formats: Iterable[str] = ("png", "pdf"),
    dpi: int = DEFAULT_DPI,
) -> dict[str, Path]:
    """Write ``folder/stem.<format>`` for each format (PNG at ``dpi``); closes the figure.

    Returns the written paths by format.
    """
    folder.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {}
    try:
        for fmt in formats:
            path = folder / f"{stem}.{fmt}"
            with atomic.atomic_path(path) as tmp:
                fig.savefig(tmp, dpi=dpi, format=fmt, metadata=_metadata(fmt))
            written[fmt] = path
    finally:
        plt.close(fig)
    return written


def _metadata(fmt: str) -> dict[str, Any] | None:
    """No creation date in vector files: the same figure gives the same bytes."""
    if fmt == "pdf":
        return {"CreationDate": None}
    if fmt == "svg":
        return {"Date": None}
    return None

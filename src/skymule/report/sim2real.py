"""The report of a ``skymule sim2real --out`` folder: figures and a "Sim-to-real" section.

Reads ``sim2real.json`` and ``sim2real_snr.csv`` only (:mod:`skymule.tasks.sim2real` writes
them); never simulates. Figures (``figures/sim2real-*.png|pdf``):

* ``sim2real-snr-time``: measured and predicted SNR over the flight, one panel per sensor,
  one line per twin;
* ``sim2real-scatter``: predicted against measured SNR, one panel per twin, the diagonal
  dashed;
* ``sim2real-policies``: per policy, the relative error of each twin's Mbit against the
  real flight's.
"""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError
from skymule.io import atomic
from skymule.io.textfiles import parse_json
from skymule.report.html import (
    FIGURES_DIR,
    REPORT_DPI,
    REPORT_FILE,
    figure_html,
    page_html,
    table_html,
)
from skymule.report.style import (
    PANEL_WIDTH_IN,
    SENSOR_PALETTE,
    finish_figure,
    panel_figure,
    paper_style,
    report_formats,
    save_figure,
    sensor_colours,
)
from skymule.tasks.sim2real import RESULT_JSON, SAMPLES_CSV

MEASURED_STYLE: dict[str, Any] = {"color": "black", "lw": 0.9}


def is_sim2real_dir(folder: Path) -> bool:
    """True for a folder ``skymule sim2real --out`` wrote."""
    return (folder / RESULT_JSON).is_file() and (folder / SAMPLES_CSV).is_file()


def _twin_colours(twins: list[str]) -> dict[str, str]:
    # twins are not sensors, but the same colour-blind-safe palette keeps them apart
    return {t: SENSOR_PALETTE[i % len(SENSOR_PALETTE)] for i, t in enumerate(twins)}


def twin_label(twin: str) -> str:
    """A twin's short name for legends: a file's name, or the scenario/preset as given."""
    return Path(twin).name if ("/" in twin or "\\" in twin) else twin


def draw_snr_time(figures: Path, samples: pd.DataFrame, formats: tuple[str, ...]) -> Path:
    sensors = list(dict.fromkeys(samples["sensor"]))
    twins = list(dict.fromkeys(samples["twin"]))
    colours = _twin_colours(twins)
    with paper_style():
        fig, axes = panel_figure(len(sensors), 2.6, sharex=True, sharey=True)
        for ax, sensor in zip(axes, sensors, strict=True):
            rows = samples[samples["sensor"] == sensor]
            first = rows[rows["twin"] == twins[0]]
            ax.plot(first["time_s"], first["measured_db"], label="measured", **MEASURED_STYLE)
            for twin in twins:
                part = rows[rows["twin"] == twin]
                ax.plot(part["time_s"], part["predicted_db"], color=colours[twin], lw=1.0,
                        label=twin_label(twin))  # fmt: skip
            ax.set_title(sensor)
            ax.set_xlabel("time [s]")
        axes[0].set_ylabel("SNR [dB]")
        finish_figure(fig, "Predicted and measured SNR along the real flight")
        written = save_figure(fig, figures, "sim2real-snr-time", formats, REPORT_DPI)
    return written["png"]


def draw_scatter(figures: Path, samples: pd.DataFrame, formats: tuple[str, ...]) -> Path:
    twins = list(dict.fromkeys(samples["twin"]))
    sensors = list(dict.fromkeys(samples["sensor"]))
    colours = sensor_colours(sensors)
    valid = samples.dropna(subset=["measured_db", "predicted_db"])
    low = float(np.nanmin(valid[["measured_db", "predicted_db"]].to_numpy())) if len(valid) else 0
    high = float(np.nanmax(valid[["measured_db", "predicted_db"]].to_numpy())) if len(valid) else 1
    with paper_style():
        fig, axes = panel_figure(len(twins), 3.2, sharex=True, sharey=True)
        for ax, twin in zip(axes, twins, strict=True):
            rows = valid[valid["twin"] == twin]
            for sensor in sensors:
                part = rows[rows["sensor"] == sensor]
                ax.scatter(part["measured_db"], part["predicted_db"], s=3, alpha=0.5,
                           color=colours[sensor], label=sensor, linewidths=0)  # fmt: skip
            ax.plot([low, high], [low, high], color="0.35", ls="--", lw=1.0)
            ax.set_title(twin_label(twin))
            ax.set_xlabel("measured SNR [dB]")
        axes[0].set_ylabel("predicted SNR [dB]")
        finish_figure(fig, "Predicted against measured SNR (dashed: equal)")
        written = save_figure(fig, figures, "sim2real-scatter", formats, REPORT_DPI)
    return written["png"]


def draw_policy_errors(figures: Path, result: dict[str, Any], formats: tuple[str, ...]) -> Path:
    twins = [t["twin"] for t in result["twins"]]
    policies = list(result["twins"][0]["policies"])
    colours = _twin_colours(twins)
    width = 0.8 / len(twins)
    with paper_style():
        fig, (ax,) = panel_figure(1, 2.9)
        for k, twin in enumerate(result["twins"]):
            errors = [twin["policies"][p]["error"] for p in policies]
            values = [100.0 * e if e is not None else np.nan for e in errors]
            x = np.arange(len(policies)) - 0.4 + (k + 0.5) * width
            ax.bar(x, values, width, color=colours[twin["twin"]], label=twin_label(twin["twin"]))
        ax.axhline(0.0, color="black", lw=0.8)
        ax.set_xticks(np.arange(len(policies)), policies)
        ax.set_ylabel("Mbit error vs real [%]")
        finish_figure(fig, "Downloads predicted by each twin along the real path")
        written = save_figure(fig, figures, "sim2real-policies", formats, REPORT_DPI)
    return written["png"]


def _number(value: Any, template: str) -> str:
    return "n/a" if value is None else template.format(value)


def sim2real_section(folder: Path, pdf: bool = True, out: Path | None = None) -> str:
    """The report section's HTML (tables and figures); writes the figures into
    ``out/figures`` (default: ``folder/figures``)."""
    figures = (out or folder) / FIGURES_DIR
    try:
        result = parse_json((folder / RESULT_JSON).read_text())
        samples = pd.read_csv(folder / SAMPLES_CSV)
    except (OSError, ValueError) as exc:
        raise SkymuleError(f"{folder}: cannot read the sim2real files ({exc})") from None
    formats = report_formats(pdf)
    snr_rows = []
    for twin in result["twins"]:
        for sensor in twin["rmse_db"]:
            coverage = (twin.get("coverage_95") or {}).get(sensor)
            snr_rows.append(
                [html.escape(twin_label(twin["twin"])), html.escape(sensor)]
                + [_number(twin[k][sensor], "{:.1f}") for k in ("rmse_db", "bias_db", "mae_db")]
                + [_number(twin["rate_rmse_mbps"][sensor], "{:.2f}"),
                   _number(None if coverage is None else 100 * coverage, "{:.0f}%")]
            )  # fmt: skip
    policy_rows = [
        [html.escape(twin_label(twin["twin"])), html.escape(policy),
         _number(v["real_mbit"], "{:.1f}"), _number(v["twin_mbit"], "{:.1f}"),
         _number(None if v["error"] is None else 100 * v["error"], "{:+.1f}%")]
        for twin in result["twins"]
        for policy, v in twin["policies"].items()
    ]  # fmt: skip
    snr_header = ["twin", "sensor", "RMSE [dB]", "bias [dB]", "MAE [dB]", "rate RMSE [Mbit/s]"]
    return (
        f"<p>Real flight <code>{html.escape(result['real'])}</code>, scenario "
        f"<code>{html.escape(result['scenario'])}</code>. SNR scores on the real flight's own "
        "samples (predicted - measured; missing samples and deep drops left out); downloads of "
        "each policy replaying the real flight against flying its recorded path under the "
        "twin.</p>"
        + table_html([*snr_header, "in the 95% interval"], snr_rows, "sim2real-snr")
        + table_html(
            ["twin", "policy", "real [Mbit]", "twin [Mbit]", "error"],
            policy_rows,
            "sim2real-policies",
        )
        + figure_html(
            "sim2real-snr-time",
            draw_snr_time(figures, samples, formats),
            "Measured SNR (black) and each twin's prediction along the real flight, per sensor.",
            PANEL_WIDTH_IN * samples["sensor"].nunique(),
        )
        + figure_html(
            "sim2real-scatter",
            draw_scatter(figures, samples, formats),
            "Predicted against measured SNR at every recorded sample, per twin.",
            PANEL_WIDTH_IN * samples["twin"].nunique(),
        )
        + figure_html(
            "sim2real-policies",
            draw_policy_errors(figures, result, formats),
            "Relative error of each twin's download along the real path, per policy.",
            PANEL_WIDTH_IN,
        )
    )


def build_sim2real_report(folder: Path, pdf: bool = True, out: Path | None = None) -> Path:
    """Write ``report.html`` with the Sim-to-real section (and its figures) into ``out``
    (default: ``folder``); returns its path."""
    section = sim2real_section(folder, pdf, out)
    page = page_html(
        f"sim2real: {folder.name}",
        f"<p>skymule sim2real report of <code>{html.escape(str(folder))}</code>.</p>",
        [("sim2real", "Sim-to-real", section)],
    )
    return atomic.write_text((out or folder) / REPORT_FILE, page)

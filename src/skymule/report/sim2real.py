"""The report of a ``skymule sim2real --out`` folder: figures and a "Sim-to-real" section.

Reads ``sim2real.json`` and ``sim2real_snr.csv`` only (:mod:`skymule.tasks.sim2real` writes
them); never simulates. The tables are the terminal's (the same cells, decimals and units:
:func:`~skymule.tasks.sim2real.snr_table` and friends). Figures
(``figures/sim2real-*.png|pdf``), small multiples that stay readable with 8 twins:

* ``sim2real-snr-time``: the SNR error (predicted - measured) over the flight, one panel per
  twin, one line per tower;
* ``sim2real-scatter``: predicted against measured SNR, one panel per twin, the diagonal
  dashed;
* ``sim2real-rmse``: each twin's and each reference's SNR RMSE with its interval, one panel
  per tower (references in grey);
* ``sim2real-ranking``: the twins in rank order, their decision regret and same-decisions
  error [%] with intervals, one marker per policy and the mean.
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
    NEUTRAL,
    PANEL_WIDTH_IN,
    POLICY_MARKERS,
    finish_figure,
    label_outer_panels,
    panel_figure,
    paper_style,
    report_formats,
    save_figure,
    sensor_colours,
)
from skymule.tasks.sim2real import (
    RESULT_JSON,
    SAMPLES_CSV,
    label_of,
    policy_table,
    ranking_table,
    snr_table,
)

MEASURED_STYLE: dict[str, Any] = {"color": "black", "lw": 0.9}
ROW_HEIGHT_IN = 0.28
"""Height per twin or reference in the interval plots [in]."""


def is_sim2real_dir(folder: Path) -> bool:
    """True for a folder ``skymule sim2real --out`` wrote."""
    return (folder / RESULT_JSON).is_file() and (folder / SAMPLES_CSV).is_file()


def twin_label(twin: str) -> str:
    """A twin's short name for legends: a file's name, or the scenario/preset as given."""
    return label_of(twin)


def draw_snr_time(figures: Path, samples: pd.DataFrame, formats: tuple[str, ...]) -> Path:
    """One panel per twin: predicted - measured SNR over the flight, a line per tower."""
    sensors = list(dict.fromkeys(samples["sensor"]))
    twins = list(dict.fromkeys(samples["twin"]))
    colours = sensor_colours(sensors)
    with paper_style():
        fig, axes = panel_figure(len(twins), 2.4, sharex=True, sharey=True)
        for ax, twin in zip(axes, twins, strict=True):
            rows = samples[samples["twin"] == twin]
            for sensor in sensors:
                part = rows[rows["sensor"] == sensor]
                error = part["predicted_db"] - part["measured_db"]
                ax.plot(part["time_s"], error, color=colours[sensor], lw=0.8, label=sensor)
            ax.axhline(0.0, **MEASURED_STYLE)
            ax.set_title(twin_label(twin))
            ax.set_xlabel("time [s]")
            ax.set_ylabel("SNR error [dB]")
        label_outer_panels(axes)
        finish_figure(fig, "SNR error (predicted - measured) along the real flight")
        written = save_figure(fig, figures, "sim2real-snr-time", formats, REPORT_DPI)
    return written["png"]


def draw_scatter(figures: Path, samples: pd.DataFrame, formats: tuple[str, ...]) -> Path:
    """One panel per twin: predicted against measured SNR, coloured by tower."""
    twins = list(dict.fromkeys(samples["twin"]))
    sensors = list(dict.fromkeys(samples["sensor"]))
    colours = sensor_colours(sensors)
    valid = samples.dropna(subset=["measured_db", "predicted_db"])
    values = valid[["measured_db", "predicted_db"]].to_numpy()
    low = float(np.nanmin(values)) if len(valid) else 0.0
    high = float(np.nanmax(values)) if len(valid) else 1.0
    with paper_style():
        fig, axes = panel_figure(len(twins), 3.0, sharex=True, sharey=True)
        for ax, twin in zip(axes, twins, strict=True):
            rows = valid[valid["twin"] == twin]
            for sensor in sensors:
                part = rows[rows["sensor"] == sensor]
                ax.scatter(part["measured_db"], part["predicted_db"], s=3, alpha=0.5,
                           color=colours[sensor], label=sensor, linewidths=0)  # fmt: skip
            ax.plot([low, high], [low, high], color="0.35", ls="--", lw=1.0)
            ax.set_title(twin_label(twin))
            ax.set_xlabel("measured SNR [dB]")
            ax.set_ylabel("predicted SNR [dB]")
        label_outer_panels(axes)
        finish_figure(fig, "Predicted against measured SNR (dashed: equal)")
        written = save_figure(fig, figures, "sim2real-scatter", formats, REPORT_DPI)
    return written["png"]


def _groups(result: dict[str, Any]) -> list[tuple[str, dict[str, Any], bool]]:
    """(label, scores, is a reference) of every twin, then every reference."""
    twins = [(twin_label(t["twin"]), t, False) for t in result["twins"]]
    refs = [(f"ref: {r['reference']}", r, True) for r in result.get("references", [])]
    return twins + refs


def _interval(value: Any, ci: Any, scale: float = 1.0) -> tuple[float, float, float]:
    """(value, distance down to low, distance up to high) for an error bar (NaN: none)."""
    if value is None:
        return (np.nan, np.nan, np.nan)
    v = float(value) * scale
    if not ci or any(c is None for c in ci):
        return (v, 0.0, 0.0)
    return (v, v - float(ci[0]) * scale, float(ci[1]) * scale - v)


def draw_rmse(figures: Path, result: dict[str, Any], formats: tuple[str, ...]) -> Path:
    """One panel per tower: SNR RMSE with its interval for every twin and reference."""
    groups = _groups(result)
    sensors = list(result["twins"][0]["rmse_db"])
    labels = [g[0] for g in groups]
    y = np.arange(len(groups))[::-1]
    height = max(2.0, 0.8 + ROW_HEIGHT_IN * len(groups))
    with paper_style():
        fig, axes = panel_figure(len(sensors), height, sharex=True, sharey=True)
        right = 1.0
        for ax, sensor in zip(axes, sensors, strict=True):
            for row, (_, scores, is_ref) in zip(y, groups, strict=True):
                ci = scores.get("ci", {}).get("rmse_db", {}).get(sensor)
                value, down, up = _interval(scores["rmse_db"].get(sensor), ci)
                right = max(right, float(np.nan_to_num(value + up)))
                colour = NEUTRAL if is_ref else "#0072B2"
                ax.errorbar(value, row, xerr=[[down], [up]], fmt="o", ms=4, color=colour,
                            capsize=2, lw=1.0,
                            label="reference" if is_ref else "twin")  # fmt: skip
            ax.set_yticks(y, labels)
            ax.set_title(sensor)
            ax.set_xlabel("SNR RMSE [dB]")
        axes[0].set_xlim(0.0, 1.05 * right)  # shared: one limit for every panel
        label_outer_panels(axes)
        finish_figure(fig, "SNR RMSE on the real flight, with 90% intervals")
        written = save_figure(fig, figures, "sim2real-rmse", formats, REPORT_DPI)
    return written["png"]


def draw_ranking(figures: Path, result: dict[str, Any], formats: tuple[str, ...]) -> Path:
    """Twins in rank order: decision regret and same-decisions error [%], with intervals."""
    ranking = result.get("ranking", [])
    by_twin = {t["twin"]: t for t in result["twins"]}
    policies = list(result["twins"][0]["policies"])
    labels = [twin_label(r["twin"]) for r in ranking]
    y = np.arange(len(ranking))[::-1]
    offsets: np.ndarray = np.linspace(-0.25, 0.25, len(policies) + 2)[1:-1]
    height = max(2.0, 0.9 + 2 * ROW_HEIGHT_IN * len(ranking))
    with paper_style():
        fig, axes = panel_figure(2, height, sharey=True)
        panels = (("regret", "decision regret [%]"), ("same_decisions_error",
                                                     "same-decisions error [%]"))  # fmt: skip
        for ax, (key, title) in zip(axes, panels, strict=True):
            for row, ranked in zip(y, ranking, strict=True):
                twin = by_twin[ranked["twin"]]
                for k, policy in enumerate(policies):
                    entry = twin["policies"][policy]
                    value, down, up = _interval(entry.get(key), entry.get(f"{key}_ci"), 100.0)
                    ax.errorbar(value, row + offsets[k], xerr=[[down], [up]], capsize=2,
                                fmt=POLICY_MARKERS[k % len(POLICY_MARKERS)], ms=4, lw=0.9,
                                color=NEUTRAL, label=policy)  # fmt: skip
                if key == "regret":
                    value, down, up = _interval(ranked["regret"], ranked["regret_ci"], 100.0)
                    ax.errorbar(value, row, xerr=[[down], [up]], fmt="o", ms=6, capsize=3,
                                color="black", lw=1.4, label="mean (ranks)")  # fmt: skip
            ax.axvline(0.0, color="0.35", lw=0.8, ls="--")
            ax.set_yticks(y, labels)
            ax.set_xlabel(title)
        finish_figure(fig, "Twins by decision regret (best at the top), with 90% intervals")
        written = save_figure(fig, figures, "sim2real-ranking", formats, REPORT_DPI)
    return written["png"]


def _html_table(table: tuple[list[str], list[dict[str, str]]], table_id: str) -> str:
    columns, rows = table
    cells = [[html.escape(str(row.get(c, ""))) for c in columns] for row in rows]
    return table_html(columns, cells, table_id)


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
    boot = result.get("bootstrap", {})
    level = (
        f"{100 * boot.get('level', 0.9):.0f}% intervals in brackets: a moving-block bootstrap, "
        f"{boot.get('block', '?')} consecutive samples a block, {boot.get('resamples', '?')} "
        f"resamples, seed {boot.get('seed', '?')}"
    )
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in result.get("notes", []))
    n_twins = samples["twin"].nunique()
    return (
        f"<p>Real flight <code>{html.escape(result['real'])}</code>, scenario "
        f"<code>{html.escape(result['scenario'])}</code>. {html.escape(level)}.</p>"
        f"<p><strong>{html.escape(result.get('trust', ''))}</strong></p>"
        + (f"<ul>{notes}</ul>" if notes else "")
        + "<p>SNR scores on the real flight's own samples (predicted - measured; missing "
        "samples and deep drops left out). Rows <code>ref: ...</code> are references, not "
        "twins: the trace's noise floor (residual from a running median), free space, "
        "log-distance fitted on the calibration set, and log-distance refitted on these very "
        "samples (an oracle).</p>"
        + _html_table(snr_table(result), "sim2real-snr")
        + "<p>Per policy, in % of the real side: the same-decisions error (the same serving "
        "decisions on the twin's and the real rates: the rate model's error), the decision "
        "regret (the policy's decisions on the twin executed on the real trace, against the "
        "policy on the real trace: what trusting the twin costs) and the policy's own error "
        "(undefined where it hovers: a hover freezes the trace's sample index, and the two "
        "sides then fly other places; the hover slots and the last sample reached are shown "
        "instead).</p>"
        + _html_table(policy_table(result), "sim2real-policies")
        + _html_table(ranking_table(result), "sim2real-ranking")
        + figure_html(
            "sim2real-ranking",
            draw_ranking(figures, result, formats),
            "Twins in rank order: decision regret (black: the mean over the policies, which "
            "ranks) and same-decisions error per policy, with 90% intervals.",
            2 * PANEL_WIDTH_IN,
        )
        + figure_html(
            "sim2real-rmse",
            draw_rmse(figures, result, formats),
            "SNR RMSE per tower with 90% intervals: twins, then the references (grey).",
            2 * PANEL_WIDTH_IN,
        )
        + figure_html(
            "sim2real-snr-time",
            draw_snr_time(figures, samples, formats),
            "SNR error (predicted - measured) along the real flight, one panel per twin.",
            PANEL_WIDTH_IN * min(2, n_twins),
        )
        + figure_html(
            "sim2real-scatter",
            draw_scatter(figures, samples, formats),
            "Predicted against measured SNR at every recorded sample, one panel per twin.",
            PANEL_WIDTH_IN * min(2, n_twins),
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

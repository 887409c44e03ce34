"""``skymule report SWEEPDIR``: one self-contained HTML report of a sweep folder.

Reads ``results.parquet`` (one row per mission: parameters + summary metrics) and
``summary.csv`` (mean and 95% CI per policy) only; never simulates. Sections:

* summary: the per-policy table of ``summary.csv`` (recomputed from the rows if it is absent);
* distributions of total downloaded data and of completion per policy (box + strip, ECDF);
* paired comparison: missions with the same parameters except the policy (``policy.name``)
  form a pair set; the ECDF of each policy's per-mission gain over a baseline, its mean with a
  95% CI (Student t) and the fractions of missions won, lost and tied;
* swept parameters: mean metric vs every swept numeric list/range parameter (a policy's own
  ``policy.params.*`` included) and, up to two figures in all, the drawn ones, per policy, with
  95% CI bands (discrete axes per value, drawn ones in quantile bins).

Figures go to ``SWEEPDIR/figures/sweep-*.png|pdf`` and are embedded as base64 PNGs.
"""

from __future__ import annotations

import html
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.axes import Axes

from skymule.errors import SkymuleError
from skymule.experiments.store import RESULTS, SUMMARY, SUMMARY_METRICS, ci95_half_width
from skymule.experiments.store import summary_table as compute_summary
from skymule.io import atomic
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
    finish_figure,
    panel_figure,
    paper_style,
    parameter_label,
    report_formats,
    save_figure,
    sensor_colours,
)

POLICY_COLUMN = "policy"
POLICY_NAME = "policy.name"
GAIN_METRIC = "total_downloaded_mbit"
#: |gain| at or below this [Mbit] (one bit) counts as a tie.
TIE_MBIT = 1e-6
#: A swept parameter with at most this many distinct values is plotted per value, else binned.
MAX_DISCRETE = 12
BINS = 6
MAX_PARAMETER_FIGURES = 2
NON_PARAMETERS = {"mission_index", "mission_id"}
#: Keys of ``metrics.summarize`` (used only when the column order does not mark the parameters).
SUMMARY_KEYS = {
    "scenario",
    "policy",
    "mission_time_s",
    "slots",
    "slot_s",
    "total_downloaded_mbit",
    "total_buffer_mbit",
    "completion",
    "handovers",
    "hover_time_s",
    "distance_m",
    "energy_kj",
    "visit_order",
    "landed_within_5m",
    "distance_to_home_m",
    "aadm_score",
}
METRIC_LABELS = {
    "total_downloaded_mbit": ("downloaded [Mbit]", "{:.1f}"),
    "completion": ("completion", "{:.3f}"),
    "handovers": ("handovers", "{:.2f}"),
    "hover_time_s": ("hover [s]", "{:.1f}"),
    "distance_m": ("distance [m]", "{:.0f}"),
    "energy_kj": ("energy [kJ]", "{:.2f}"),
    "aadm_score": ("AADM score", "{:.1f}"),
}


def is_sweep_dir(path: Path) -> bool:
    return (path / RESULTS).is_file()


@dataclass(frozen=True)
class Gain:
    """Per-mission gain of ``policy`` over the baseline on paired missions."""

    policy: str
    values: np.ndarray  # policy - baseline [Mbit], one per pair

    @property
    def n(self) -> int:
        return int(self.values.size)

    @property
    def mean(self) -> float:
        return float(np.mean(self.values)) if self.n else float("nan")

    @property
    def ci95(self) -> float:
        return ci95_half_width(self.values)

    @property
    def median(self) -> float:
        return float(np.median(self.values)) if self.n else float("nan")

    @property
    def wins(self) -> float:
        return float(np.mean(self.values > TIE_MBIT)) if self.n else float("nan")

    @property
    def losses(self) -> float:
        return float(np.mean(self.values < -TIE_MBIT)) if self.n else float("nan")

    @property
    def ties(self) -> float:
        return 1.0 - self.wins - self.losses if self.n else float("nan")


@dataclass(frozen=True)
class Paired:
    baseline: str
    keys: list[str]  # the parameter columns that identify a pair set
    groups: int  # pair sets with every policy exactly once
    skipped: int  # pair sets missing a policy or holding one twice
    gains: list[Gain]


@dataclass(frozen=True)
class SweptParameter:
    label: str
    x: np.ndarray  # one per row of the results
    discrete: bool


def read_results(folder: Path) -> pd.DataFrame:
    path = folder / RESULTS
    try:
        results = pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises many types for a damaged file
        raise SkymuleError(f"{path}: cannot read ({type(exc).__name__}: {exc})") from None
    missing = [c for c in (POLICY_COLUMN, GAIN_METRIC) if c not in results.columns]
    if missing:
        raise SkymuleError(
            f"{path}: missing column(s) {', '.join(missing)}; expected the results.parquet "
            "written by `skymule sweep`"
        )
    if results.empty:
        raise SkymuleError(f"{path}: no missions; run `skymule sweep FILE --out DIR` first")
    results = results.copy()
    results[POLICY_COLUMN] = results[POLICY_COLUMN].astype(str)
    return results


def parameter_columns(results: pd.DataFrame) -> list[str]:
    """The sweep's parameter columns: between ``mission_id`` and the summary (``scenario``)."""
    cols = list(results.columns)
    if "mission_id" in cols and "scenario" in cols:
        start, stop = cols.index("mission_id") + 1, cols.index("scenario")
        if start <= stop:
            return cols[start:stop]
    return [
        c
        for c in cols
        if c not in NON_PARAMETERS and c not in SUMMARY_KEYS and not c.startswith("per_sensor_")
    ]


def read_summary(folder: Path, results: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """``summary.csv`` when it is readable and complete, else the same table from the rows."""
    path = folder / SUMMARY
    metrics = [m for m in SUMMARY_METRICS if m in results.columns]
    wanted = {"policy", "missions", *(f"{m}_{s}" for m in metrics for s in ("mean", "ci95"))}
    if path.is_file():
        try:
            table = pd.read_csv(path)
        except (OSError, ValueError, pd.errors.ParserError):
            table = pd.DataFrame()
        if wanted <= set(table.columns):
            table["policy"] = table["policy"].astype(str)
            return table, SUMMARY
    levels = [
        c
        for c in parameter_columns(results)
        if c not in (POLICY_NAME, "seed") and not c.endswith(".seed")
        and results[c].nunique() <= MAX_DISCRETE  # list axes; drawn ones vary per mission
    ]  # fmt: skip
    return compute_summary(results, levels), f"{RESULTS} (no complete {SUMMARY})"


def default_baseline(policies: list[str]) -> str:
    return "greedy" if "greedy" in policies else sorted(policies)[0]


def paired_gains(
    results: pd.DataFrame, params: list[str], baseline: str, metric: str = GAIN_METRIC
) -> Paired | None:
    """Gains over ``baseline`` on pair sets: rows equal in every non-policy parameter."""
    policies = sorted(results[POLICY_COLUMN].unique())
    if len(policies) < 2:
        return None
    keys = [p for p in params if p not in (POLICY_NAME, POLICY_COLUMN)]
    frame = results[[*keys, POLICY_COLUMN, metric]].copy()
    if keys:
        # one hashable key per row (NaN-safe, type-stable) for the pair sets
        frame["_pair"] = pd.util.hash_pandas_object(frame[keys], index=False).to_numpy()
    else:
        frame["_pair"] = 0
    counts = frame.groupby(["_pair", POLICY_COLUMN]).size().unstack(fill_value=0)
    complete = counts.index[(counts == 1).all(axis=1)]
    wide = frame[frame["_pair"].isin(complete)].pivot(
        index="_pair", columns=POLICY_COLUMN, values=metric
    )
    gains = [
        Gain(p, (wide[p] - wide[baseline]).to_numpy(float))
        for p in policies
        if p != baseline and len(wide)
    ]
    return Paired(baseline, keys, len(wide), int(len(counts) - len(complete)), gains)


def swept_parameters(results: pd.DataFrame, params: list[str]) -> list[SweptParameter]:
    """The numeric parameters that vary: every discrete one (a policy's parameters too), then
    drawn ones while there are fewer than :data:`MAX_PARAMETER_FIGURES`.

    Seeds are replicate indices, not treatments, and are left out; ``sensors[i].field``
    columns form one parameter (their sum for buffers, else their mean).
    """
    groups: dict[str, list[str]] = {}
    for col in params:
        if col == POLICY_NAME or col == "seed" or col.endswith(".seed"):
            continue
        series = results[col]
        if not pd.api.types.is_numeric_dtype(series) or pd.api.types.is_bool_dtype(series):
            continue
        match = re.fullmatch(r"(.*)\[\d+\](.*)", col)
        key = f"{match.group(1)}[*]{match.group(2)}" if match else col
        groups.setdefault(key, []).append(col)
    found: list[SweptParameter] = []
    for key, cols in groups.items():
        values = results[cols].to_numpy(float)
        words = parameter_label(key)
        if len(cols) == 1:
            x, label = values[:, 0], words
            match = re.fullmatch(r"sensors\[(\d+)\]\..*", key)
            if match:
                label = f"sensor {int(match.group(1)) + 1} {words}"
        elif key.endswith("buffer_mbit"):
            x, label = values.sum(axis=1), f"total {words}"
        else:
            x, label = values.mean(axis=1), f"mean sensor {words}"
        distinct = np.unique(x[np.isfinite(x)])
        if distinct.size > 1:
            found.append(SweptParameter(label, x, bool(distinct.size <= MAX_DISCRETE)))
    discrete = [p for p in found if p.discrete]
    drawn = [p for p in found if not p.discrete]
    return discrete + drawn[: max(0, MAX_PARAMETER_FIGURES - len(discrete))]


def policy_colours(policies: list[str]) -> dict[str, str]:
    """Policies take the sensors' palette (distinct, colour-blind safe, never black)."""
    return sensor_colours(policies)


def _ecdf(ax: Axes, values: np.ndarray, **kwargs: object) -> None:
    values = np.sort(values[np.isfinite(values)])
    if values.size:
        y = np.arange(1, values.size + 1) / values.size
        ax.step(np.r_[values[0], values], np.r_[0.0, y], where="post", **kwargs)  # type: ignore[arg-type]


#: Missions drawn as dots per policy at most: beyond a few hundred dots a strip is a blob
#: (the box and the CDF summarise every mission).
STRIP_POINTS = 300


def sweep_title(results: pd.DataFrame, what: str = "") -> str:
    """What a sweep figure is about: the scenario (name, sensors, length), the missions and
    ``what``; from results.parquet alone."""
    names = (
        ", ".join(sorted(results["scenario"].astype(str).unique())) if "scenario" in results else ""
    )
    sensors = sum(c.startswith("per_sensor_buffer_mbit.") for c in results.columns)
    lengths: list[float] = []
    if "mission_time_s" in results:
        lengths = [float(v) for v in results["mission_time_s"].unique()]
    parts = [p for p in (names, f"{sensors} sensors" if sensors else "") if p]
    if len(lengths) == 1:
        parts.append(f"{lengths[0]:.0f} s")
    head = f"{', '.join(parts)}: " if parts else ""
    return f"{head}{len(results):,} missions" + (f"; {what}" if what else "")


def strip_sample(values: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """At most :data:`STRIP_POINTS` of ``values``, drawn without replacement (seeded)."""
    if values.size <= STRIP_POINTS:
        return values
    return rng.choice(values, STRIP_POINTS, replace=False)


def draw_distribution(
    results: pd.DataFrame, metric: str, label: str, folder: Path, stem: str, pdf: bool
) -> Path:
    """Box + jittered strip per policy (left; at most :data:`STRIP_POINTS` dots a policy),
    ECDF per policy (right)."""
    policies = sorted(results[POLICY_COLUMN].unique())
    colours = policy_colours(policies)
    data = [results.loc[results[POLICY_COLUMN] == p, metric].to_numpy(float) for p in policies]
    data = [d[np.isfinite(d)] for d in data]
    rng = np.random.default_rng(0)
    sampled = any(values.size > STRIP_POINTS for values in data)
    with paper_style():
        fig, (box, cdf) = panel_figure(2, 2.6)
        box.boxplot(data, widths=0.5, showfliers=False, medianprops={"color": "#000000"})
        for i, (policy, values) in enumerate(zip(policies, data, strict=True), start=1):
            shown = strip_sample(values, rng)
            jitter = rng.uniform(-0.18, 0.18, shown.size)
            box.scatter(i + jitter, shown, s=4, alpha=0.45, color=colours[policy], lw=0)
            box.plot(i, values.mean() if values.size else np.nan, "D", color="#000000", ms=3)
            _ecdf(cdf, values, color=colours[policy], label=policy)
        box.plot([], [], "D", color="#000000", ms=3, ls="", label="mean")
        box.set_xticks(range(1, len(policies) + 1), policies)
        box.set_ylabel(label)
        box.set_title(f"per mission ({STRIP_POINTS} dots a policy)" if sampled else "per mission")
        cdf.set_xlabel(label)
        cdf.set_ylabel("fraction of missions")
        cdf.set_title("empirical CDF")
        finish_figure(fig, sweep_title(results))
        return save_figure(fig, folder, stem, report_formats(pdf), REPORT_DPI)["png"]


def draw_gains(
    paired: Paired, policies: list[str], folder: Path, pdf: bool, title: str = ""
) -> Path:
    colours = policy_colours(policies)
    with paper_style():
        fig, (ax,) = panel_figure(1, 2.9)
        for gain in paired.gains:
            label = (
                f"{gain.policy}: mean {gain.mean:+.1f} ± {gain.ci95:.1f} Mbit, "
                f"wins {100 * gain.wins:.0f}%, losses {100 * gain.losses:.0f}%"
            )
            _ecdf(ax, gain.values, color=colours[gain.policy], label=label)
            ax.axvline(gain.mean, color=colours[gain.policy], ls="--", lw=1.0)
            if np.isfinite(gain.ci95):
                low, high = gain.mean - gain.ci95, gain.mean + gain.ci95
                ax.axvspan(low, high, color=colours[gain.policy], alpha=0.15, lw=0)
        ax.axvline(0.0, color="#000000", lw=0.8)
        ax.set_xlabel(f"gain over {paired.baseline} per mission [Mbit]")
        ax.set_ylabel("fraction of missions")
        finish_figure(fig, title or f"Paired gain over {paired.baseline}", columns=1)
        return save_figure(fig, folder, "sweep-gain", report_formats(pdf), REPORT_DPI)["png"]


def _binned(x: np.ndarray, discrete: bool) -> tuple[np.ndarray, np.ndarray]:
    """Bin index per row and the x of each bin (the value, or the median in the bin)."""
    finite = np.isfinite(x)
    if discrete:
        centres = np.unique(x[finite])
        index = np.searchsorted(centres, np.where(finite, x, centres[0]))
        return np.where(finite, index, -1), centres
    edges = np.unique(np.quantile(x[finite], np.linspace(0, 1, BINS + 1)))
    index = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
    index = np.where(finite, index, -1)
    centres = np.array([np.median(x[index == b]) for b in range(edges.size - 1)])
    return index, centres


def draw_parameter(
    results: pd.DataFrame, parameter: SweptParameter, number: int, folder: Path, pdf: bool
) -> Path:
    policies = sorted(results[POLICY_COLUMN].unique())
    colours = policy_colours(policies)
    index, centres = _binned(parameter.x, parameter.discrete)
    metrics = [m for m in (GAIN_METRIC, "completion") if m in results.columns]
    with paper_style():
        fig, axes = panel_figure(len(metrics), 2.6)
        for ax, metric in zip(axes, metrics, strict=True):
            values = results[metric].to_numpy(float)
            for policy in policies:
                mine = results[POLICY_COLUMN].to_numpy() == policy
                stats = [values[mine & (index == b)] for b in range(centres.size)]
                mean = np.array([s.mean() if s.size else np.nan for s in stats])
                half = np.array([ci95_half_width(s) for s in stats])
                ax.plot(centres, mean, "o-", ms=3, color=colours[policy], label=policy)
                ax.fill_between(
                    centres, mean - half, mean + half, color=colours[policy], alpha=0.2, lw=0
                )
            ax.set_xlabel(parameter.label + ("" if parameter.discrete else " (binned)"))
            ax.set_ylabel(f"mean {METRIC_LABELS[metric][0]}")
        finish_figure(fig, sweep_title(results, f"mean vs {parameter.label} (bands: 95% CI)"))
        stem = f"sweep-parameter-{number}"
        return save_figure(fig, folder, stem, report_formats(pdf), REPORT_DPI)["png"]


def _num(value: float, template: str) -> str:
    return "-" if not np.isfinite(value) else template.format(value)


def summary_levels(summary: pd.DataFrame) -> list[str]:
    """The swept treatments of ``summary.csv``: its columns between policy and missions."""
    columns = list(summary.columns)
    if columns[:1] != ["policy"] or "missions" not in columns:
        return []
    return columns[1 : columns.index("missions")]


def summary_html(summary: pd.DataFrame, source: str) -> str:
    metrics = [m for m in METRIC_LABELS if f"{m}_mean" in summary.columns]
    levels = summary_levels(summary)
    rows = []
    for _, row in summary.iterrows():
        cells = [html.escape(str(row["policy"]))]
        cells += [html.escape(_level(row[c])) for c in levels]
        cells.append(str(int(row["missions"])))
        for metric in metrics:
            fmt = METRIC_LABELS[metric][1]
            mean, half = float(row[f"{metric}_mean"]), float(row[f"{metric}_ci95"])
            cells.append(f"{_num(mean, fmt)} ± {_num(half, fmt)}")
        rows.append(cells)
    header = [
        "policy",
        *(_column_label(c) for c in levels),
        "missions",
        *(METRIC_LABELS[m][0] for m in metrics),
    ]
    per = "per policy" + (" and swept value" if levels else "")
    return (
        f"<p>Mean ± 95% CI half-width (Student t) {per}, from <code>{html.escape(source)}"
        "</code>.</p>" + table_html(header, rows, "sweep-summary-table")
    )


def _column_label(column: str) -> str:
    """A parameter column in words (``sensors[1].buffer_mbit`` -> ``sensor 2 buffer [Mbit]``)."""
    match = re.fullmatch(r"sensors\[(\d+)\]\..*", column)
    words = parameter_label(column)
    return f"sensor {int(match.group(1)) + 1} {words}" if match else words


def _level(value: object) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def gain_html(paired: Paired) -> str:
    rows = []
    for g in paired.gains:
        attrs = (
            f'data-policy="{html.escape(g.policy)}" data-n="{g.n}" data-mean="{g.mean!r}" '
            f'data-ci95="{g.ci95!r}" data-wins="{g.wins!r}" data-losses="{g.losses!r}" '
            f'data-ties="{g.ties!r}"'
        )
        cells = [
            html.escape(g.policy),
            str(g.n),
            _num(g.mean, "{:+.2f}"),
            _num(g.ci95, "{:.2f}"),
            f"[{_num(g.mean - g.ci95, '{:+.2f}')}, {_num(g.mean + g.ci95, '{:+.2f}')}]",
            _num(g.median, "{:+.2f}"),
            _num(100 * g.wins, "{:.1f}%"),
            _num(100 * g.losses, "{:.1f}%"),
            _num(100 * g.ties, "{:.1f}%"),
        ]
        rows.append(f'<tr class="gain" {attrs}>' + "".join(f"<td>{c}</td>" for c in cells))
    header = [
        "policy",
        "pairs",
        "mean gain [Mbit]",
        "95% CI ±",
        "95% CI",
        "median [Mbit]",
        "wins",
        "losses",
        "ties",
    ]
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    table = (
        f'<table id="gain-table"><thead><tr>{head}</tr></thead>'
        f"<tbody>{''.join(r + '</tr>' for r in rows)}</tbody></table>"
    )
    keys = ", ".join(f"<code>{html.escape(k)}</code>" for k in paired.keys) or "(none)"
    skipped = (
        f" {paired.skipped} parameter set(s) without exactly one mission per policy were left out."
        if paired.skipped
        else ""
    )
    return (
        f"<p>Baseline <b>{html.escape(paired.baseline)}</b>. Missions are paired when every "
        f"parameter except the policy ones is equal ({keys}): {paired.groups} pair sets.{skipped}"
        f" Gain = total downloaded of the policy − that of the baseline on the same mission; "
        f"win/loss: gain above/below ±{TIE_MBIT:g} Mbit.</p>{table}"
    )


def parameters_html(results: pd.DataFrame, params: list[str]) -> str:
    rows = []
    for col in params:
        series = results[col]
        distinct = series.nunique(dropna=False)
        if pd.api.types.is_numeric_dtype(series) and not pd.api.types.is_bool_dtype(series):
            span = f"{series.min():.6g} … {series.max():.6g}"
        else:
            shown = [str(v) for v in series.drop_duplicates().head(6)]
            span = ", ".join(shown) + (" …" if distinct > 6 else "")
        rows.append([f"<code>{html.escape(col)}</code>", str(distinct), html.escape(span)])
    return table_html(["parameter", "distinct values", "values"], rows, "parameter-table")


def build_sweep_report(
    folder: Path, pdf: bool = True, baseline: str | None = None, out: Path | None = None
) -> Path:
    """Write ``report.html`` and ``figures/sweep-*.png|pdf`` of a sweep folder into ``out``
    (default: ``folder``); returns the HTML."""
    results = read_results(folder)
    params = parameter_columns(results)
    summary, source = read_summary(folder, results)
    policies = sorted(results[POLICY_COLUMN].unique())
    if baseline is None:
        baseline = default_baseline(policies)
    elif baseline not in policies:
        raise SkymuleError(
            f"--baseline {baseline}: not a policy of {folder / RESULTS}; "
            f"allowed: {', '.join(policies)}"
        )
    figures = (out or folder) / FIGURES_DIR
    sections: list[tuple[str, str, str]] = [("summary", "Summary", summary_html(summary, source))]
    dist = figure_html(
        "sweep-download",
        draw_distribution(
            results, GAIN_METRIC, "downloaded [Mbit]", figures, "sweep-download", pdf
        ),
        "Total data downloaded per mission, per policy: box (quartiles, whiskers 1.5 IQR) over "
        f"every mission, with up to {STRIP_POINTS} missions a policy as dots, and the "
        "empirical CDF.",
        2 * PANEL_WIDTH_IN,
    )
    if "completion" in results.columns:
        dist += figure_html(
            "sweep-completion",
            draw_distribution(
                results, "completion", "completion", figures, "sweep-completion", pdf
            ),
            "Completion (downloaded / buffered) per mission, per policy.",
            2 * PANEL_WIDTH_IN,
        )
    sections.append(("distributions", "Distributions", dist))
    paired = paired_gains(results, params, baseline)
    if paired is None:
        content = "<p>One policy only: nothing to pair.</p>"
    elif not paired.groups:
        content = (
            "<p>No paired missions: no parameter set (all parameters except the policy ones) "
            "holds exactly one mission per policy.</p>"
        )
    else:
        content = figure_html(
            "sweep-gain",
            draw_gains(
                paired, policies, figures, pdf, sweep_title(results, f"gain over {baseline}")
            ),
            f"Empirical CDF of the per-mission gain in total downloaded data over "
            f"{paired.baseline} on paired missions; dashed: mean gain, shaded: its 95% CI.",
            PANEL_WIDTH_IN,
        ) + gain_html(paired)
    sections.append(("paired", "Paired comparison", content))
    swept = swept_parameters(results, params)
    if swept:
        content = "".join(
            figure_html(
                f"sweep-parameter-{i}",
                draw_parameter(results, p, i, figures, pdf),
                f"Mean downloaded data and completion vs {p.label} per policy; bands: 95% CI of "
                "the mean" + ("." if p.discrete else f" ({BINS} quantile bins, x: bin median)."),
                2 * PANEL_WIDTH_IN,
            )
            for i, p in enumerate(swept, start=1)
        )
    else:
        content = "<p>No swept numeric parameter besides seeds and the policy.</p>"
    sections.append(("parameters", "Swept parameters", content + parameters_html(results, params)))
    scenario = ", ".join(map(str, results["scenario"].unique())) if "scenario" in results else ""
    title = f"{scenario or folder.name}: sweep of {len(results)} missions"
    intro = (
        f"<p>skymule report of <code>{html.escape(str(folder))}</code> (sweep folder, "
        f"{len(results)} missions, policies: {html.escape(', '.join(policies))}).</p>"
    )
    page = page_html(title, intro, sections)
    return atomic.write_text((out or folder) / REPORT_FILE, page)

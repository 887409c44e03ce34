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
import pyarrow as pa
import pyarrow.parquet as pq
from matplotlib.axes import Axes

from skymule.errors import SkymuleError
from skymule.experiments.store import (
    RESULTS,
    SUMMARY,
    SUMMARY_METRICS,
    summary_of,
    t_half_width,
)
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
from skymule.report.sweep_query import (
    EXACT_VALUES,
    ResultsQuery,
    finite,
    literal,
    quoted,
    results_query,
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
    """Per-mission gain of ``policy`` over the baseline on paired missions: its statistics
    and its ECDF (every gain, or quantiles of many)."""

    policy: str
    n: int
    mean: float
    std: float
    median: float
    wins: float  # fraction of pairs with gain > TIE_MBIT
    losses: float
    ecdf_x: np.ndarray
    ecdf_y: np.ndarray

    @property
    def ci95(self) -> float:
        return t_half_width(self.n, self.std)

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
    expression: str  # SQL over the results' columns
    discrete: bool


@dataclass(frozen=True)
class Results:
    """A sweep folder's results.parquet: its columns and row count, queried out of core."""

    path: Path
    schema: pa.Schema
    n: int

    @property
    def columns(self) -> list[str]:
        return list(self.schema.names)


def read_results(folder: Path) -> Results:
    """The schema and size of ``folder/results.parquet``, checked (its rows stay on disk)."""
    path = folder / RESULTS
    try:
        meta = pq.read_metadata(path)
        schema = meta.schema.to_arrow_schema()
    except Exception as exc:  # pyarrow raises many types for a damaged file
        raise SkymuleError(f"{path}: cannot read ({type(exc).__name__}: {exc})") from None
    missing = [c for c in (POLICY_COLUMN, GAIN_METRIC) if c not in schema.names]
    if missing:
        raise SkymuleError(
            f"{path}: missing column(s) {', '.join(missing)}; expected the results.parquet "
            "written by `skymule sweep`"
        )
    if meta.num_rows == 0:
        raise SkymuleError(f"{path}: no missions; run `skymule sweep FILE --out DIR` first")
    return Results(path, schema, int(meta.num_rows))


def parameter_columns(columns: list[str]) -> list[str]:
    """The sweep's parameter columns: between ``mission_id`` and the summary (``scenario``)."""
    cols = list(columns)
    if "mission_id" in cols and "scenario" in cols:
        start, stop = cols.index("mission_id") + 1, cols.index("scenario")
        if start <= stop:
            return cols[start:stop]
    return [
        c
        for c in cols
        if c not in NON_PARAMETERS and c not in SUMMARY_KEYS and not c.startswith("per_sensor_")
    ]


def read_summary(folder: Path, results: Results, query: ResultsQuery) -> tuple[pd.DataFrame, str]:
    """``summary.csv`` when it is readable and complete, else the same table from the rows
    (streamed, per policy and value of each list axis as :func:`summary_levels_of` finds
    them)."""
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
    return summary_of(results.path, summary_levels_of(query, results)), (
        f"{RESULTS} (no complete {SUMMARY})"
    )


def summary_levels_of(query: ResultsQuery, results: Results) -> list[str]:
    """The parameter columns a summary is split by when only the rows are left: the list
    axes, told from drawn ones by their few distinct values (seeds and the policy aside)."""
    levels = []
    for column in parameter_columns(results.columns):
        if column in (POLICY_NAME, "seed") or column.endswith(".seed"):
            continue
        name = quoted(column)
        # HyperLogLog first: an exact count of millions of distinct draws costs a hash table
        if query.approx_distinct(name) > 4 * MAX_DISCRETE:
            continue
        ((distinct,),) = query.rows(f"SELECT count(DISTINCT {name}) FROM results")
        if distinct <= MAX_DISCRETE:
            levels.append(column)
    return levels


def default_baseline(policies: list[str]) -> str:
    return "greedy" if "greedy" in policies else sorted(policies)[0]


def _ecdf_of(
    query: ResultsQuery, table: str, column: str, n: int, least: float, largest: float
) -> tuple[np.ndarray, np.ndarray]:
    """The ECDF of a column of a temporary table: every value, or a fine histogram of many."""
    if n <= EXACT_VALUES:
        found = query.rows(f"SELECT {column} FROM {table} WHERE {column} IS NOT NULL")
        x = np.sort(np.array([v for (v,) in found], float))
        return x, np.arange(1, x.size + 1) / max(x.size, 1)
    source = f"SELECT {column} AS x FROM {table} WHERE {column} IS NOT NULL"
    return query.histogram_ecdf(source, least, largest)


def paired_gains(
    query: ResultsQuery,
    params: list[str],
    policies: list[str],
    baseline: str,
    metric: str = GAIN_METRIC,
) -> Paired | None:
    """Gains over ``baseline`` on pair sets: rows equal in every non-policy parameter."""
    if len(policies) < 2:
        return None
    keys = [p for p in params if p not in (POLICY_NAME, POLICY_COLUMN)]
    policy = f"CAST({quoted(POLICY_COLUMN)} AS VARCHAR)"
    columns = []
    for i, name in enumerate(policies):
        columns.append(f"count(*) FILTER (WHERE {policy} = {literal(name)}) AS c{i}")
        columns.append(
            f"max(CAST({quoted(metric)} AS DOUBLE)) FILTER (WHERE {policy} = {literal(name)}) "
            f"AS v{i}"
        )
    group = f" GROUP BY {', '.join(quoted(k) for k in keys)}" if keys else ""
    query.con.execute(
        f"CREATE TEMP TABLE pair_sets AS SELECT {', '.join(columns)} FROM results{group}"
    )
    complete = " AND ".join(f"c{i} = 1" for i in range(len(policies)))
    base = policies.index(baseline)
    gains = []
    others = [(i, p) for i, p in enumerate(policies) if p != baseline]
    query.con.execute(
        "CREATE TEMP TABLE gains AS SELECT "
        + ", ".join(f"v{i} - v{base} AS g{i}" for i, _ in others)
        + f" FROM pair_sets WHERE {complete}"
    )
    ((groups, total),) = query.rows(
        f"SELECT count(*) FILTER (WHERE {complete}), count(*) FROM pair_sets"
    )
    for i, name in others:
        g = f"g{i}"
        ((n, mean, std, median, wins, losses, least, largest),) = query.rows(
            f"SELECT count({g}), avg({g}), stddev_samp({g}), quantile_cont({g}, 0.5), "
            f"avg(CAST({g} > {TIE_MBIT!r} AS DOUBLE)), avg(CAST({g} < {-TIE_MBIT!r} AS DOUBLE)), "
            f"min({g}), max({g}) FROM gains"
        )
        if not n:
            continue
        x, y = _ecdf_of(query, "gains", g, int(n), least, largest)
        nan = float("nan")
        gains.append(
            Gain(
                name,
                int(n),
                float(mean),
                nan if std is None else float(std),
                float(median),
                float(wins),
                float(losses),
                x,
                y,
            )
        )
    query.con.execute("DROP TABLE gains")
    query.con.execute("DROP TABLE pair_sets")
    return Paired(baseline, keys, int(groups), int(total - groups), gains)


def _is_number(field: pa.Field) -> bool:
    return pa.types.is_integer(field.type) or pa.types.is_floating(field.type)


def swept_parameters(
    query: ResultsQuery, schema: pa.Schema, params: list[str]
) -> list[SweptParameter]:
    """The numeric parameters that vary: every discrete one (a policy's parameters too), then
    drawn ones while there are fewer than :data:`MAX_PARAMETER_FIGURES`.

    Seeds are replicate indices, not treatments, and are left out; ``sensors[i].field``
    columns form one parameter (their sum for buffers, else their mean).
    """
    groups: dict[str, list[str]] = {}
    for col in params:
        if col == POLICY_NAME or col == "seed" or col.endswith(".seed"):
            continue
        if not _is_number(schema.field(col)):
            continue
        match = re.fullmatch(r"(.*)\[\d+\](.*)", col)
        key = f"{match.group(1)}[*]{match.group(2)}" if match else col
        groups.setdefault(key, []).append(col)
    found: list[SweptParameter] = []
    for key, cols in groups.items():
        terms = [f"CAST({quoted(c)} AS DOUBLE)" for c in cols]
        words = parameter_label(key)
        if len(cols) == 1:
            expression, label = terms[0], words
            match = re.fullmatch(r"sensors\[(\d+)\]\..*", key)
            if match:
                label = f"sensor {int(match.group(1)) + 1} {words}"
        elif key.endswith("buffer_mbit"):
            expression, label = "(" + " + ".join(terms) + ")", f"total {words}"
        else:
            expression = "((" + " + ".join(terms) + f") / {len(terms)})"
            label = f"mean sensor {words}"
        x = finite(expression)
        # HyperLogLog first: an exact count of millions of distinct draws costs a hash table
        if query.approx_distinct(x) > 4 * MAX_DISCRETE:
            found.append(SweptParameter(label, expression, False))
            continue
        ((distinct,),) = query.rows(f"SELECT count(DISTINCT {x}) FROM results")
        if distinct > 1:
            found.append(SweptParameter(label, expression, bool(distinct <= MAX_DISCRETE)))
    discrete = [p for p in found if p.discrete]
    drawn = [p for p in found if not p.discrete]
    return discrete + drawn[: max(0, MAX_PARAMETER_FIGURES - len(discrete))]


def policy_colours(policies: list[str]) -> dict[str, str]:
    """Policies take the sensors' palette (distinct, colour-blind safe, never black)."""
    return sensor_colours(policies)


def _ecdf(ax: Axes, x: np.ndarray, y: np.ndarray, **kwargs: object) -> None:
    if x.size:
        ax.step(np.r_[x[0], x], np.r_[0.0, y], where="post", **kwargs)  # type: ignore[arg-type]


#: Missions drawn as dots per policy at most: beyond a few hundred dots a strip is a blob
#: (the box and the CDF summarise every mission).
STRIP_POINTS = 300


def sweep_title(query: ResultsQuery, results: Results, what: str = "") -> str:
    """What a sweep figure is about: the scenario (name, sensors, length), the missions and
    ``what``; from results.parquet alone (queried, not loaded)."""
    names, lengths = "", []
    if "scenario" in results.columns:
        found = query.rows(f"SELECT DISTINCT CAST({quoted('scenario')} AS VARCHAR) FROM results")
        names = ", ".join(sorted(str(v) for (v,) in found))
    if "mission_time_s" in results.columns:
        found = query.rows(f"SELECT DISTINCT {quoted('mission_time_s')} FROM results LIMIT 2")
        lengths = [float(v) for (v,) in found]
    sensors = sum(c.startswith("per_sensor_buffer_mbit.") for c in results.columns)
    parts = [p for p in (names, f"{sensors} sensors" if sensors else "") if p]
    if len(lengths) == 1:
        parts.append(f"{lengths[0]:.0f} s")
    head = f"{', '.join(parts)}: " if parts else ""
    return f"{head}{results.n:,} missions" + (f"; {what}" if what else "")


def strip_sample(values: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """At most :data:`STRIP_POINTS` of ``values``, drawn without replacement (seeded)."""
    if values.size <= STRIP_POINTS:
        return values
    return rng.choice(values, STRIP_POINTS, replace=False)


def draw_distribution(
    query: ResultsQuery,
    policies: list[str],
    metric: str,
    label: str,
    folder: Path,
    stem: str,
    pdf: bool,
    title: str,
) -> Path:
    """Box + jittered strip per policy (left; at most :data:`STRIP_POINTS` dots a policy),
    ECDF per policy (right)."""
    colours = policy_colours(policies)
    found = query.distribution(metric, POLICY_COLUMN)
    rng = np.random.default_rng(0)
    sampled = any(d.n > STRIP_POINTS for d in found.values())
    with paper_style():
        fig, (box, cdf) = panel_figure(2, 2.6)
        shown = [(i, p) for i, p in enumerate(policies, start=1) if p in found]
        box.bxp(
            [found[p].box for _, p in shown],
            positions=[i for i, _ in shown],
            widths=0.5,
            showfliers=False,
            medianprops={"color": "#000000"},
        )
        for i, policy in shown:
            dist = found[policy]
            dots = strip_sample(dist.dots, rng)
            jitter = rng.uniform(-0.18, 0.18, dots.size)
            box.scatter(i + jitter, dots, s=4, alpha=0.45, color=colours[policy], lw=0)
            box.plot(i, dist.mean, "D", color="#000000", ms=3)
            _ecdf(cdf, dist.ecdf_x, dist.ecdf_y, color=colours[policy], label=policy)
        box.plot([], [], "D", color="#000000", ms=3, ls="", label="mean")
        box.set_xticks(range(1, len(policies) + 1), policies)
        box.set_ylabel(label)
        box.set_title(f"per mission ({STRIP_POINTS} dots a policy)" if sampled else "per mission")
        cdf.set_xlabel(label)
        cdf.set_ylabel("fraction of missions")
        cdf.set_title("empirical CDF")
        finish_figure(fig, title)
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
            _ecdf(ax, gain.ecdf_x, gain.ecdf_y, color=colours[gain.policy], label=label)
            ax.axvline(gain.mean, color=colours[gain.policy], ls="--", lw=1.0)
            if np.isfinite(gain.ci95):
                low, high = gain.mean - gain.ci95, gain.mean + gain.ci95
                ax.axvspan(low, high, color=colours[gain.policy], alpha=0.15, lw=0)
        ax.axvline(0.0, color="#000000", lw=0.8)
        ax.set_xlabel(f"gain over {paired.baseline} per mission [Mbit]")
        ax.set_ylabel("fraction of missions")
        finish_figure(fig, title or f"Paired gain over {paired.baseline}", columns=1)
        return save_figure(fig, folder, "sweep-gain", report_formats(pdf), REPORT_DPI)["png"]


def _bins(query: ResultsQuery, parameter: SweptParameter) -> tuple[str, np.ndarray]:
    """A SQL bin number per row and the x of each bin (the value, or the median in the bin);
    rows whose parameter is not finite get NULL."""
    x = finite(parameter.expression)
    if parameter.discrete:
        found = query.rows(f"SELECT DISTINCT {x} AS v FROM results WHERE v IS NOT NULL ORDER BY v")
        centres = np.array([v for (v,) in found], float)
        cases = " ".join(f"WHEN {x} = {float(v)!r} THEN {i}" for i, v in enumerate(centres))
        return f"CASE {cases} END", centres
    probs = [b / BINS for b in range(BINS + 1)]
    edges: np.ndarray = np.unique(np.array(query.quantiles(parameter.expression, probs)))
    above = " + ".join(f"CAST({x} >= {float(e)!r} AS INTEGER)" for e in edges)
    last = edges.size - 2
    bin_sql = f"CASE WHEN {x} IS NOT NULL THEN LEAST(GREATEST({above} - 1, 0), {last}) END"
    medians = dict(
        query.rows(
            f"SELECT b, quantile_cont(x, 0.5) FROM (SELECT {bin_sql} AS b, {x} AS x "
            "FROM results) WHERE b IS NOT NULL GROUP BY b"
        )
    )
    return bin_sql, np.array([medians.get(b, np.nan) for b in range(edges.size - 1)], float)


def draw_parameter(
    query: ResultsQuery,
    policies: list[str],
    metrics: list[str],
    parameter: SweptParameter,
    number: int,
    folder: Path,
    pdf: bool,
    title: str,
) -> Path:
    colours = policy_colours(policies)
    bin_sql, centres = _bins(query, parameter)
    policy = f"CAST({quoted(POLICY_COLUMN)} AS VARCHAR)"
    with paper_style():
        fig, axes = panel_figure(len(metrics), 2.6)
        for ax, metric in zip(axes, metrics, strict=True):
            stats = query.moments(metric, [policy, bin_sql])
            for name in policies:
                cells = [stats.get((name, b)) for b in range(centres.size)]
                mean = np.array([c.mean if c else np.nan for c in cells])
                half = np.array([t_half_width(c.n, c.std) if c else np.nan for c in cells])
                ax.plot(centres, mean, "o-", ms=3, color=colours[name], label=name)
                ax.fill_between(
                    centres, mean - half, mean + half, color=colours[name], alpha=0.2, lw=0
                )
            ax.set_xlabel(parameter.label + ("" if parameter.discrete else " (binned)"))
            ax.set_ylabel(f"mean {METRIC_LABELS[metric][0]}")
        finish_figure(fig, f"{title}; mean vs {parameter.label} (bands: 95% CI)")
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


#: Distinct values counted exactly up to about this many (HyperLogLog's estimate beyond).
EXACT_DISTINCT = 100_000


def parameters_html(query: ResultsQuery, schema: pa.Schema, params: list[str]) -> str:
    rows = []
    for col in params:
        name = quoted(col)
        distinct = query.approx_distinct(name)
        shown_count = f"≈{distinct:,}"
        if distinct <= EXACT_DISTINCT:
            ((exact,),) = query.rows(f"SELECT count(DISTINCT {name}) FROM results")
            shown_count = str(exact)
        field = schema.field(col)
        if _is_number(field):
            ((low, high),) = query.rows(f"SELECT min({name}), max({name}) FROM results")
            span = f"{low:.6g} … {high:.6g}" if low is not None else "-"
        else:
            first = query.rows(
                f"SELECT {name} FROM results GROUP BY {name} ORDER BY min(file_row_number) LIMIT 7"
            )
            span = ", ".join(str(v) for (v,) in first[:6]) + (" …" if len(first) > 6 else "")
        rows.append([f"<code>{html.escape(col)}</code>", shown_count, html.escape(span)])
    return table_html(["parameter", "distinct values", "values"], rows, "parameter-table")


def build_sweep_report(
    folder: Path, pdf: bool = True, baseline: str | None = None, out: Path | None = None
) -> Path:
    """Write ``report.html`` and ``figures/sweep-*.png|pdf`` of a sweep folder into ``out``
    (default: ``folder``); returns the HTML.

    The rows stay on disk: every statistic is a DuckDB query over results.parquet
    (:mod:`skymule.report.sweep_query`), so ten million missions report in constant memory.
    """
    results = read_results(folder)
    with results_query(results.path, results.schema) as query:
        summary, source = read_summary(folder, results, query)
        policies = query.distinct(POLICY_COLUMN)
        if baseline is None:
            baseline = default_baseline(policies)
        elif baseline not in policies:
            raise SkymuleError(
                f"--baseline {baseline}: not a policy of {folder / RESULTS}; "
                f"allowed: {', '.join(policies)}"
            )
        figures = (out or folder) / FIGURES_DIR
        sections = _sections(query, figures, results, summary, source, policies, baseline, pdf)
        scenarios = query.distinct("scenario") if "scenario" in results.columns else []
    scenario = ", ".join(scenarios)
    title = f"{scenario or folder.name}: sweep of {results.n} missions"
    intro = (
        f"<p>skymule report of <code>{html.escape(str(folder))}</code> (sweep folder, "
        f"{results.n} missions, policies: {html.escape(', '.join(policies))}).</p>"
    )
    page = page_html(title, intro, sections)
    return atomic.write_text((out or folder) / REPORT_FILE, page)


def _sections(
    query: ResultsQuery,
    figures: Path,
    results: Results,
    summary: pd.DataFrame,
    source: str,
    policies: list[str],
    baseline: str,
    pdf: bool,
) -> list[tuple[str, str, str]]:
    params = parameter_columns(results.columns)
    sections: list[tuple[str, str, str]] = [("summary", "Summary", summary_html(summary, source))]
    title = sweep_title(query, results)
    dist = figure_html(
        "sweep-download",
        draw_distribution(
            query,
            policies,
            GAIN_METRIC,
            "downloaded [Mbit]",
            figures,
            "sweep-download",
            pdf,
            title,
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
                query,
                policies,
                "completion",
                "completion",
                figures,
                "sweep-completion",
                pdf,
                title,
            ),
            "Completion (downloaded / buffered) per mission, per policy.",
            2 * PANEL_WIDTH_IN,
        )
    sections.append(("distributions", "Distributions", dist))
    paired = paired_gains(query, params, policies, baseline)
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
            draw_gains(paired, policies, figures, pdf, f"{title}; gain over {baseline}"),
            f"Empirical CDF of the per-mission gain in total downloaded data over "
            f"{paired.baseline} on paired missions; dashed: mean gain, shaded: its 95% CI.",
            PANEL_WIDTH_IN,
        ) + gain_html(paired)
    sections.append(("paired", "Paired comparison", content))
    swept = swept_parameters(query, results.schema, params)
    metrics = [m for m in (GAIN_METRIC, "completion") if m in results.columns]
    if swept:
        content = "".join(
            figure_html(
                f"sweep-parameter-{i}",
                draw_parameter(query, policies, metrics, p, i, figures, pdf, title),
                f"Mean downloaded data and completion vs {p.label} per policy; bands: 95% CI of "
                "the mean" + ("." if p.discrete else f" ({BINS} quantile bins, x: bin median)."),
                2 * PANEL_WIDTH_IN,
            )
            for i, p in enumerate(swept, start=1)
        )
    else:
        content = "<p>No swept numeric parameter besides seeds and the policy.</p>"
    table = parameters_html(query, results.schema, params)
    sections.append(("parameters", "Swept parameters", content + table))
    return sections

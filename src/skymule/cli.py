"""The ``skymule`` command line.

User mistakes (bad scenario, trace, flag) print one line and exit with status 2; the
library raises :class:`~skymule.errors.SkymuleError` for them and this module turns it into
that line. Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich import box
from rich.console import Console
from rich.table import Table

from skymule.errors import SkymuleError
from skymule.metrics import HEADLINE_METRICS

if TYPE_CHECKING:
    from skymule.bounds.result import MissionBound
    from skymule.geo import LocalFrame
    from skymule.radio.sources import SignalSource
    from skymule.scenario import Scenario
    from skymule.world import Mission

app = typer.Typer(
    add_completion=False,
    pretty_exceptions_enable=False,
    no_args_is_help=True,
    help="UAV data-mule missions: simulate, replay, compare and plot.",
)
# tables are wider than 80 columns: piped output keeps every digit
console = Console(width=None if sys.stdout.isatty() else 120)

SUMMARY_COLUMNS = ("policy", *HEADLINE_METRICS)


COLUMN_LABELS = {
    "total_downloaded_mbit": "Mbit",
    "completion": "done",
    "handovers": "switches",
    "hover_time_s": "hover s",
    "distance_m": "dist m",
    "energy_kj": "kJ",
    "aadm_score": "AADM",
    "gap_to_bound_mbit": "gap Mbit",
    "gap_to_bound_frac": "gap",
}
"""Short terminal headers (the files keep the full field names)."""

LEFT_ALIGNED = {"policy", "quantity", "source", "sensor"}


def _table(title: str, rows: list[dict], columns: tuple[str, ...]) -> Table:
    table = Table(title=title, box=box.SIMPLE_HEAD, pad_edge=False)
    for column in columns:
        table.add_column(
            COLUMN_LABELS.get(column, column),
            justify="left" if column in LEFT_ALIGNED else "right",
            no_wrap=True,
            min_width=max(
                [len(COLUMN_LABELS.get(column, column))]
                + [len(_fmt(row.get(column, ""))) for row in rows]
            ),
        )
    for row in rows:
        table.add_row(*(_fmt(row.get(c, "")) for c in columns))
    return table


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) < 10 else f"{value:.1f}"
    return str(value)


def _per_sensor_table(summary: dict) -> Table:
    table = Table(title=f"{summary['scenario']} - {summary['policy']}")
    for column in ("sensor", "buffer [Mbit]", "downloaded [Mbit]"):
        table.add_column(column, justify="right")
    for name, buffer in summary["per_sensor_buffer_mbit"].items():
        table.add_row(name, f"{buffer:.1f}", f"{summary['per_sensor_downloaded_mbit'][name]:.1f}")
    table.add_row(
        "total", f"{summary['total_buffer_mbit']:.1f}", f"{summary['total_downloaded_mbit']:.1f}"
    )
    return table


@app.command()
def run(
    scenario: Annotated[str, typer.Argument(help="Scenario TOML path or preset name.")],
    out: Annotated[Path | None, typer.Option("--out", help="Run folder to write.")] = None,
    policy: Annotated[str | None, typer.Option("--policy", help="Override the policy.")] = None,
) -> None:
    """Run one mission and print its summary."""
    from skymule.runner import simulate
    from skymule.scenario import load_scenario

    result = simulate(load_scenario(scenario), policy)
    if out is not None:
        result.write(out)
    console.print(_per_sensor_table(result.summary))
    console.print(_table("summary", [result.summary], SUMMARY_COLUMNS))
    if out is not None:
        console.print(f"wrote {out}/summary.json, slots.csv, scenario.json")


@app.command()
def compare(
    scenario: Annotated[str, typer.Argument(help="Scenario TOML path or preset name.")],
    policies: Annotated[
        str, typer.Option("--policies", help="Comma-separated policy names.")
    ] = "greedy,hgad",
    out: Annotated[Path | None, typer.Option("--out", help="Folder to write.")] = None,
    sources: Annotated[
        str | None,
        typer.Option(
            "--sources",
            help="Compare signal sources instead: e.g. fspl,al-hourani,radiomap:map.json "
            "(path-loss model names, radiomap:FILE, scenario); one table, SNR-CDF panels.",
        ),
    ] = None,
) -> None:
    """Run one scenario under several policies on identical signal draws."""
    import pandas as pd

    from skymule.policies import POLICIES, unknown_policies
    from skymule.runner import simulate
    from skymule.scenario import load_scenario
    from skymule.world import build_mission

    names = [p.strip() for p in policies.split(",") if p.strip()]
    unknown = unknown_policies(names)
    if not names or unknown:
        raise SkymuleError(
            f"--policies {policies!r}: unknown {', '.join(unknown) or '(empty)'}; "
            f"allowed: {', '.join(sorted(POLICIES))}"
        )
    base = load_scenario(scenario)
    if sources is not None:
        _compare_sources(base, sources, names, out)
        return
    mission = build_mission(base)
    upper, note = _bound_or_note(mission)
    rows = []
    for name in names:
        result = simulate(base, name, mission=mission)
        if out is not None:
            result.write(out / name.replace("/", "_"))  # rl:dir/model.zip: one folder
        rows.append(_with_gap(_flat(result.summary), upper))
    table = pd.DataFrame(rows)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        table.to_csv(out / "comparison.csv", index=False)
        if upper is not None:
            _write_bound(out, upper)
    shown = rows if upper is None else [*rows, _bound_row(upper)]
    console.print(_table(f"{base.name}: comparison", shown, (*SUMMARY_COLUMNS, *GAP_COLUMNS)))
    if note is not None:
        console.print(f"no upper bound: {note}", markup=False)
    if out is not None:
        console.print(f"wrote {out}/comparison.csv and one folder per policy")


GAP_COLUMNS = ("gap_to_bound_mbit", "gap_to_bound_frac")
"""compare: bound - downloaded [Mbit] and that gap as a fraction of the bound."""


def _bound_or_note(mission: Mission) -> tuple[MissionBound | None, str | None]:
    """(the mission's upper bound, None), or (None, why there is none) for compare."""
    from skymule.bounds.mission import mission_bound
    from skymule.bounds.result import BoundError

    try:
        return mission_bound(mission), None
    except BoundError as exc:
        return None, str(exc)


def _with_gap(row: dict, upper: MissionBound | None) -> dict:
    """``row`` plus upper_bound_mbit and the gap columns (unchanged without a bound)."""
    if upper is None:
        return row
    bound_mbit = upper.upper_bound_bit / 1e6
    gap = bound_mbit - row["total_downloaded_mbit"]
    frac = gap / bound_mbit if bound_mbit > 0 else 0.0
    return {**row, "upper_bound_mbit": bound_mbit, GAP_COLUMNS[0]: gap, GAP_COLUMNS[1]: frac}


def _bound_row(upper: MissionBound, **extra: object) -> dict:
    """The "bound" row of a printed comparison: only the total is filled."""
    return {**extra, "policy": "bound", "total_downloaded_mbit": upper.upper_bound_bit / 1e6}


def _write_bound(folder: Path, upper: MissionBound) -> Path:
    """Write ``folder/bound.json`` (Mbit) and return its path."""
    import json

    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "bound.json"
    path.write_text(json.dumps(upper.to_json_dict(), indent=2) + "\n")
    return path


def _compare_sources(base: Scenario, sources: str, policies: list[str], out: Path | None) -> None:
    """``compare --sources``: every source x policy in one table; SNR-CDF panels with --out."""
    import pandas as pd

    from skymule.sources_compare import compare_sources, folder_name, parse_sources

    results = compare_sources(base, parse_sources(sources), policies)
    bounds = {spec: _bound_or_note(result.mission) for spec, _, result in results}
    rows = [
        {"source": spec, **_with_gap(_flat(result.summary), bounds[spec][0])}
        for spec, _, result in results
    ]
    shown = []
    for row, (spec, policy, _) in zip(rows, results, strict=True):
        shown.append(row)
        upper = bounds[spec][0]
        if policy == policies[-1] and upper is not None:
            shown.append(_bound_row(upper, source=spec))
    columns = ("source", *SUMMARY_COLUMNS, *GAP_COLUMNS)
    console.print(_table("signal sources", shown, columns))
    for spec, (_, note) in bounds.items():
        if note is not None:
            console.print(f"{spec}: no upper bound: {note}", markup=False)
    if out is None:
        return
    from skymule.io.runs import read_run
    from skymule.report.channel import plot_snr_cdf_by_source

    panels = []
    for spec, policy, result in results:
        folder = out / folder_name(spec) / policy
        result.write(folder)
        if policy == policies[0]:
            panels.append((spec, read_run(folder)[1]))
    pd.DataFrame(rows).to_csv(out / "comparison.csv", index=False)
    figure = out / "snr_cdf_by_source.png"
    plot_snr_cdf_by_source(panels, figure, f"SNR CDF ({policies[0]})")
    console.print(f"wrote {out}/comparison.csv, {figure} and one folder per source/policy")


def _flat(summary: dict) -> dict:
    row = {k: v for k, v in summary.items() if not isinstance(v, dict | list)}
    for name, value in summary["per_sensor_downloaded_mbit"].items():
        row[f"downloaded_mbit_{name}"] = value
    return row


@app.command()
def bound(
    scenario: Annotated[str, typer.Argument(help="Scenario TOML path or preset name.")],
    out: Annotated[Path | None, typer.Option("--out", help="Folder for bound.json.")] = None,
) -> None:
    """Upper bound on the data any policy can download in a scenario (LP/MILP, HiGHS)."""
    from skymule.bounds.mission import mission_bound
    from skymule.scenario import load_scenario
    from skymule.world import build_mission

    upper = mission_bound(build_mission(load_scenario(scenario)))
    record = upper.to_json_dict()
    rows = [{"quantity": k, "value": v} for k, v in record.items() if v is not None]
    console.print(_table(f"{record['scenario']}: upper bound", rows, ("quantity", "value")))
    if out is not None:
        console.print(f"wrote {_write_bound(out, upper)}")


@app.command()
def plot(
    run_dir: Annotated[Path, typer.Argument(help="A run folder (or compare folder).")],
) -> None:
    """Draw a run's figures from its files (never re-simulates)."""
    from skymule.io.runs import is_run_dir, read_run
    from skymule.report.figures import plot_run

    folders = (
        [run_dir]
        if is_run_dir(run_dir)
        else sorted(p for p in run_dir.iterdir() if p.is_dir() and is_run_dir(p))
        if run_dir.is_dir()
        else []
    )
    if not folders:
        read_run(run_dir)  # raises the clear "not a run folder" error
    for folder in folders:
        summary, slots = read_run(folder)
        for path in plot_run(folder, summary, slots):
            console.print(f"wrote {path}")


@app.command()
def report(
    run_dir: Annotated[Path, typer.Argument(help="A run, compare or sweep folder.")],
    pdf: Annotated[bool, typer.Option("--pdf/--no-pdf", help="Also write vector PDFs.")] = True,
    baseline: Annotated[
        str | None,
        typer.Option(help="Sweep folders: policy the paired gains are over (default greedy)."),
    ] = None,
) -> None:
    """Write DIR/report.html (self-contained) and DIR/figures/*.png|pdf from its files."""
    from skymule.report.build import build_report

    path = build_report(run_dir, pdf=pdf, baseline=baseline)
    console.print(f"wrote {path} and {run_dir / 'figures'}/*.png, *.pdf")


@app.command()
def export(
    run_dir: Annotated[Path, typer.Argument(help="A run folder.")],
    kml: Annotated[bool, typer.Option("--kml", help="Write flight.kml.")] = False,
    geojson: Annotated[bool, typer.Option("--geojson", help="Write flight.geojson.")] = False,
    plan: Annotated[
        bool, typer.Option("--plan", help="Write mission.plan (QGroundControl; autonomous runs).")
    ] = False,
) -> None:
    """Export a run's path, towers, geofence and hover points (KML/GeoJSON) or its mission."""
    from skymule.io.exports import export_run

    chosen = [name for name, on in (("kml", kml), ("geojson", geojson), ("plan", plan)) if on]
    for path in export_run(run_dir, chosen):
        console.print(f"wrote {path}")


@app.command()
def analyze(
    log: Annotated[Path, typer.Argument(help="AADM merged log or digital-twin export (CSV).")],
    out: Annotated[Path | None, typer.Option("--out", help="Compare folder to write.")] = None,
    volumes: Annotated[
        Path | None, typer.Option("--volumes", help="AADM volume file (Mbit a line).")
    ] = None,
    buffers: Annotated[
        str | None, typer.Option("--buffers", help="Mbit: one value for all or one per tower.")
    ] = None,
    download_log: Annotated[
        Path | None, typer.Option("--download-log", help="The flight's time,tower,mbit log.")
    ] = None,
    policies: Annotated[
        str, typer.Option("--policies", help="Comma-separated policy names.")
    ] = "greedy,hgad",
    pdf: Annotated[bool, typer.Option("--pdf/--no-pdf", help="Also write vector PDFs.")] = True,
) -> None:
    """Replay a recorded flight under several policies and write a compare folder + report."""
    from skymule.analyze import analyze_flight
    from skymule.report.build import build_report

    out_dir = out if out is not None else Path(f"{log.stem}-analysis")
    rows = analyze_flight(
        log,
        out_dir,
        policies=[p.strip() for p in policies.split(",") if p.strip()],
        volumes=volumes,
        buffers=buffers,
        download_log=download_log,
    )
    console.print(_table(f"{log.name}: replay", rows, SUMMARY_COLUMNS))
    report_path = build_report(out_dir, pdf=pdf)
    console.print(f"wrote {out_dir}/comparison.csv, one folder per run, {report_path}")


@app.command()
def scenarios() -> None:
    """List the built-in scenario presets."""
    from skymule.scenario import load_scenario, preset_names

    table = Table(title="built-in scenarios")
    table.add_column("name")
    table.add_column("mode")
    table.add_column("source")
    table.add_column("duration [s]", justify="right")
    table.add_column("sensors")
    for name in preset_names():
        spec = load_scenario(name)
        table.add_row(
            name,
            spec.trajectory.mode,
            spec.signal.source,
            _fmt(spec.mission.duration_s),
            ", ".join(f"{s.name}:{s.buffer_mbit:g}" for s in spec.sensors),
        )
    console.print(table)


@app.command()
def sweep(
    sweep_file: Annotated[Path, typer.Argument(help="Sweep TOML (base scenario + axes).")],
    out: Annotated[Path, typer.Option("--out", help="Sweep folder (resumed if it exists).")],
    executor: Annotated[
        str, typer.Option("--executor", help="inprocess, process, dask-local or dask.")
    ] = "process",
    workers: Annotated[
        int | None, typer.Option("--workers", help="Workers (default: all cores).")
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Dask scheduler tcp://HOST:PORT.")
    ] = None,
    chunk_size: Annotated[int, typer.Option("--chunk-size", help="Missions per chunk.")] = 500,
    quiet: Annotated[bool, typer.Option("--quiet", help="No progress bar.")] = False,
) -> None:
    """Run many missions (resumable); results.parquet and summary.csv in --out."""
    from skymule.experiments.run import run_sweep
    from skymule.experiments.sweep import load_sweep

    spec = load_sweep(sweep_file)
    outcome = run_sweep(
        spec,
        out,
        executor=executor,
        workers=workers,
        scheduler=scheduler,
        chunk_size=chunk_size,
        progress=not quiet,
    )
    table = Table(title=f"{sweep_file.name}: {outcome.n_missions} missions (mean ± 95% CI)")
    metrics = ("total_downloaded_mbit", "completion", "handovers", "hover_time_s", "distance_m")
    for column in ("policy", "missions", *metrics):
        table.add_column(
            COLUMN_LABELS.get(column, column), justify="left" if column == "policy" else "right"
        )
    for row in outcome.summary.to_dict("records"):
        cells = [f"{_fmt(row[f'{m}_mean'])} ± {_fmt(row[f'{m}_ci95'])}" for m in metrics]
        table.add_row(str(row["policy"]), str(row["missions"]), *cells)
    console.print(table)
    console.print(
        f"ran {outcome.n_run} of {outcome.n_missions} missions in {outcome.seconds:.1f} s; "
        f"wrote {out}/results.parquet and {out}/summary.csv"
    )


def _origin_frame(origin: str | None, default: tuple[float, float]) -> LocalFrame:
    """LocalFrame at ``--origin LAT,LON`` or at ``default``."""
    from skymule.geo import LocalFrame

    if origin is None:
        return LocalFrame(*default)
    try:
        lat, lon = (float(v) for v in origin.split(","))
    except ValueError:
        raise SkymuleError(
            f"--origin {origin!r}: expected LAT,LON in degrees, e.g. 35.7274824,-78.6962749"
        ) from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise SkymuleError(f"--origin {origin!r}: latitude must be -90..90, longitude -180..180")
    return LocalFrame(lat, lon)


@app.command("fit-radiomap")
def fit_radiomap_command(
    traces: Annotated[list[Path], typer.Argument(help="Recorded flights (AADM log / DT export).")],
    out: Annotated[Path, typer.Option("--out", help="Map file to write (JSON).")],
    scenario: Annotated[
        str | None,
        typer.Option("--scenario", help="Take sensors, positions and origin from a scenario."),
    ] = None,
    origin: Annotated[
        str | None, typer.Option("--origin", help="LAT,LON of the local frame's origin.")
    ] = None,
    drop_below: Annotated[
        float, typer.Option("--drop-below", help="SNR below this [dB] is a deep drop.")
    ] = -40.0,
    json_out: Annotated[bool, typer.Option("--json", help="Print the fit as JSON.")] = False,
) -> None:
    """Fit a radio map (log-distance + kriged residual) per sensor to recorded flights."""
    import json

    from skymule.geo import sensor_positions_m
    from skymule.io.traces import read_trace
    from skymule.radio.radiomap import fit_radiomap, site_tower_positions_m
    from skymule.radio.sources import model_source
    from skymule.scenario import RadioSpec, SiteSpec, load_scenario

    spec = load_scenario(scenario) if scenario else None
    site = spec.site.origin if spec else SiteSpec().origin
    frame = _origin_frame(origin, (site.lat, site.lon))
    if spec is not None:
        names = spec.signal.sensors_from_trace or [s.name for s in spec.sensors]
        sensor_m = sensor_positions_m(spec.sensors, frame)
        radio = spec.radio
    else:
        names = list(read_trace(traces[0]).columns)
        sensor_m = site_tower_positions_m(names, frame)
        radio = RadioSpec()
    baseline = model_source(radio.model_copy(update={"model": "fspl"}), sensor_m)
    fitted = fit_radiomap(
        traces,
        names,
        sensor_m,
        frame,
        drop_below_db=drop_below,
        baseline=baseline,
    )
    fitted.write(out)
    rows = [
        {
            "sensor": m.name,
            "exponent": m.exponent,
            "intercept_db": m.intercept_db,
            "sigma_db": m.variogram.sill_db2**0.5,
            "range_m": m.variogram.range_m,
            "nugget_db": m.variogram.nugget_db2**0.5,
            **m.stats,
        }
        for m in fitted.sensors
    ]
    if json_out:
        print(json.dumps({"map": str(out), "sensors": rows}, indent=2))
        return
    columns = (
        "sensor", "exponent", "intercept_db", "sigma_db", "range_m", "nugget_db", "n_used",
        "n_missing", "n_deep_drops", "rmse_db", "cv_rmse_map_db", "cv_rmse_trend_db",
        "cv_rmse_baseline_db",
    )  # fmt: skip
    title = "radio map fit (cv: held-out trace segments; baseline: fspl)"
    console.print(_table(title, rows, columns))
    console.print(f"wrote {out}")


@app.command("score-radiomap")
def score_radiomap_command(
    source: Annotated[str, typer.Argument(help="A fitted map (.json) or a scenario/preset.")],
    trace: Annotated[Path, typer.Argument(help="Recorded flight to score against.")],
    origin: Annotated[
        str | None, typer.Option("--origin", help="LAT,LON of the local frame's origin.")
    ] = None,
    json_out: Annotated[bool, typer.Option("--json", help="Print the scores as JSON.")] = False,
) -> None:
    """How well a radio map (or a scenario's model) predicts a recorded flight."""
    import json

    import numpy as np

    from skymule.geo import sensor_positions_m
    from skymule.io.traces import positions_local, read_trace
    from skymule.radio.channel import signal_source
    from skymule.radio.radiomap import frame_offset_m, read_radiomap, score_source
    from skymule.radio.rates import rate_bps, resolve_rate_table
    from skymule.scenario import RadioSpec, load_scenario

    if source.lower().endswith(".json"):
        fitted = read_radiomap(Path(source))
        frame = _origin_frame(origin, fitted.origin)
        names = list(fitted.names)
        model: SignalSource = fitted.source(names, frame_offset_m(fitted.origin, frame))
        radio = RadioSpec()
        table = resolve_rate_table(radio.rate_table)
    else:
        spec = load_scenario(source)
        if spec.signal.source == "trace":
            raise SkymuleError(
                f"{source}: signal.source = 'trace' replays a flight and predicts nothing; "
                "score a scenario with a model or radiomap source"
            )
        frame = _origin_frame(origin, (spec.site.origin.lat, spec.site.origin.lon))
        names = spec.signal.sensors_from_trace or [s.name for s in spec.sensors]
        sensor_m = sensor_positions_m(spec.sensors, frame)
        model = signal_source(spec, frame, sensor_m)
        radio = spec.radio
        table = resolve_rate_table(radio.rate_table, Path(spec.base_dir))
    recorded = read_trace(trace, sensors=names)
    positions = positions_local(recorded, frame.to_local)
    predicted = np.asarray(model.snr_db(positions))
    scores = score_source(
        predicted, recorded.snr_db, names, lambda snr: rate_bps(table, snr, radio.bandwidth_hz)
    )
    if json_out:
        print(json.dumps(scores, indent=2))
        return
    rows = [{"sensor": n, **{k: v[n] for k, v in scores.items()}} for n in names]
    columns = ("sensor", *scores)
    console.print(_table(f"{source} vs {trace} (predicted - measured)", rows, columns))


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the app, turning user mistakes into one line and exit status 2.

    Click handles bad flags itself (usage line, exit 2); library errors that are the
    user's doing arrive as SkymuleError.
    """
    try:
        app(args=argv)
    except SkymuleError as exc:
        print(f"skymule: error: {exc}", file=sys.stderr)
        sys.exit(2)
    except OSError as exc:
        # a file or folder the user named cannot be read or written (permissions, full disk)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"skymule: error: {where}{exc.strerror or exc}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("skymule: interrupted", file=sys.stderr)
        sys.exit(130)

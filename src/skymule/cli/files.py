"""Commands that read and write files: plot, report, export, analyze, radio maps."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import typer

import skymule.cli.output as output
from skymule.cli.folders import guard_analysis, inspect_folder
from skymule.cli.missions import TrustOption
from skymule.cli.tables import print_table
from skymule.errors import SkymuleError
from skymule.io.textfiles import json_safe


def plot(
    run_dir: Annotated[Path, typer.Argument(help="A run folder (or compare folder).")],
    fmt: Annotated[str, typer.Option("--format", help="Comma-separated: png, pdf, svg.")] = "png",
    dpi: Annotated[int, typer.Option("--dpi", help="Raster resolution [dpi].")] = 300,
) -> None:
    """Draw a run's figures from its files (never re-simulates)."""
    from skymule.io.runs import read_run
    from skymule.report.plot import plot_run
    from skymule.report.style import check_dpi, parse_formats

    formats = parse_formats(fmt)
    check_dpi(dpi)
    if inspect_folder(run_dir).kind == "sweep":
        raise SkymuleError(
            f"{run_dir}: a sweep folder; its figures come with `skymule report {run_dir}` "
            "(report.html and figures/sweep-*.png), plot draws run and compare folders"
        )
    folders = run_folders(run_dir)
    if not folders:
        read_run(run_dir)  # raises the clear "not a run folder" error
    for folder in folders:
        summary, slots = read_run(folder)
        for path in plot_run(folder, summary, slots, formats=formats, dpi=dpi):
            output.say(f"wrote {path}")


def run_folders(folder: Path) -> list[Path]:
    """The run folders in ``folder``: itself, its policies (compare), or its sources'
    policies (``compare --sources``)."""
    from skymule.io.runs import is_run_dir

    if is_run_dir(folder):
        return [folder]
    if not folder.is_dir():
        return []
    inside = sorted(p for p in folder.iterdir() if p.is_dir())
    return [p for p in inside if is_run_dir(p)] or [
        run for p in inside for run in sorted(p.iterdir()) if run.is_dir() and is_run_dir(run)
    ]


def _report(folder: Path, pdf: bool, baseline: str | None = None) -> Path:
    from skymule.report.build import build_report

    return build_report(folder, pdf=pdf, baseline=baseline)  # --no-pdf drops old PDFs


def report(
    run_dir: Annotated[Path, typer.Argument(help="A run, compare or sweep folder.")],
    pdf: Annotated[bool, typer.Option("--pdf/--no-pdf", help="Also write vector PDFs.")] = True,
    baseline: Annotated[
        str | None,
        typer.Option(help="Sweep folders: policy the paired gains are over (default greedy)."),
    ] = None,
) -> None:
    """Write DIR/report.html (self-contained) and DIR/figures/*.png|pdf from its files."""
    from skymule.cli.missions import warn
    from skymule.report.inputs import bound_warnings

    path = _report(run_dir, pdf, baseline)
    # a compare folder's bound whose condition fails is drawn as invalid: say so here too
    warn([f"{run_dir / 'bound.json'}: {w}" for w in bound_warnings(run_dir)])
    kinds = "*.png, *.pdf" if pdf else "*.png"
    output.say(f"wrote {path} and {run_dir / 'figures'}/{kinds}")


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
        output.say(f"wrote {path}")


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
    force: Annotated[
        bool, typer.Option("--force", help="Write into --out even if it holds something else.")
    ] = False,
    trust_model: TrustOption = None,
) -> None:
    """Replay a recorded flight under several policies and write a compare folder + report."""
    from skymule.cli.missions import summary_columns
    from skymule.tasks.analyze import DEFAULT_BUFFER_MBIT, analyze_flight

    out_dir = out if out is not None else Path(f"{log.stem}-analysis")
    guard_analysis(out_dir, force)
    rows = analyze_flight(
        log,
        out_dir,
        policies=[p.strip() for p in policies.split(",") if p.strip()],
        volumes=volumes,
        buffers=buffers,
        download_log=download_log,
    )
    if volumes is None and buffers is None:
        output.say(
            f"note: no --volumes or --buffers given; assumed {DEFAULT_BUFFER_MBIT:g} Mbit per tower"
        )
    print_table(output.console, f"{log.name}: replay", rows, summary_columns())
    report_path = _report(out_dir, pdf)
    output.say(f"wrote {out_dir}/comparison.csv, one folder per run, {report_path}")


OriginOption = Annotated[
    str | None, typer.Option("--origin", help="LAT,LON of the local frame's origin.")
]


def check_seed(seed: int) -> None:
    """``--seed``: numpy's generators take non-negative seeds only; one line otherwise."""
    if seed < 0:
        raise SkymuleError(f"--seed {seed}: allowed: a whole number 0 or above")


def fit_radiomap_command(
    traces: Annotated[list[Path], typer.Argument(help="Recorded flights (AADM log / DT export).")],
    out: Annotated[Path, typer.Option("--out", help="Map file to write (JSON).")],
    scenario: Annotated[
        str | None,
        typer.Option("--scenario", help="Take sensors, positions and origin from a scenario."),
    ] = None,
    origin: OriginOption = None,
    drop_below: Annotated[
        float, typer.Option("--drop-below", help="SNR below this [dB] is a deep drop.")
    ] = -40.0,
    method: Annotated[
        str,
        typer.Option(
            "--method",
            help="kriging (log-distance + kriged residual), log-distance, gp (kriging with "
            "maximum-likelihood parameters) or neural (a learned twin: falls back to a simpler "
            "model when blocked cross-validation says the networks do not beat it).",
        ),
    ] = "kriging",
    prior: Annotated[
        str | None,
        typer.Option(
            "--prior",
            help="neural: learn the residual over this twin (map .json, flight .csv, scenario).",
        ),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="neural: seed of the networks.")] = 0,
    json_out: Annotated[bool, typer.Option("--json", help="Print the fit as JSON.")] = False,
) -> None:
    """Fit a radio map per sensor to recorded flights (a signal source like any map)."""
    from skymule.cli.missions import _working
    from skymule.tasks.radiomaps import fit_radiomap_files, parse_origin

    check_seed(seed)
    with _working(f"fitting the radio map ({method})"):
        fit = fit_radiomap_files(
            traces,
            scenario=scenario,
            origin=parse_origin(origin) if origin else None,
            drop_below_db=drop_below,
            method=method,
            prior=prior,
            seed=seed,
        )
    fit.fitted.write(out)
    for warning in fit.warnings:
        print(f"skymule: warning: {warning}", file=sys.stderr)
    if json_out:
        shown = {"map": str(out), "method": method, "sensors": fit.rows}
        print(json.dumps({**shown, "warnings": list(fit.warnings), "note": fit.note}, indent=2))
        return
    from skymule.radio.radiomap import CV_BUFFER_M

    held_out = f"blocked: held-out segments, {CV_BUFFER_M:g} m buffer"
    title = f"radio map fit, {method} (cv: {held_out}; baseline: fspl)"
    print_table(output.console, title, fit.rows, fit.columns())
    if fit.note:
        output.say(fit.note)
    output.say(f"wrote {out}")


def score_radiomap_command(
    source: Annotated[str, typer.Argument(help="A fitted map (.json) or a scenario/preset.")],
    trace: Annotated[Path, typer.Argument(help="Recorded flight to score against.")],
    origin: OriginOption = None,
    json_out: Annotated[bool, typer.Option("--json", help="Print the scores as JSON.")] = False,
) -> None:
    """How well a radio map (or a scenario's model) predicts a recorded flight."""
    from skymule.tasks.radiomaps import parse_origin, score_against_trace

    scores = score_against_trace(source, trace, origin=parse_origin(origin) if origin else None)
    if json_out:  # a score that is not a number (no samples) is null: NaN is not JSON
        print(json.dumps(json_safe(scores), indent=2, allow_nan=False))
        return
    names = list(next(iter(scores.values())))
    rows = [{"sensor": n, **{k: v[n] for k, v in scores.items()}} for n in names]
    title = f"{source} vs {trace} (predicted - measured)"
    print_table(output.console, title, rows, ("sensor", *scores))


def sim2real_command(
    scenario: Annotated[
        str, typer.Argument(help="Scenario or preset: sensors, buffers, link budget, policies.")
    ],
    real_trace: Annotated[Path, typer.Argument(help="The real flight (merged log / DT export).")],
    twin: Annotated[
        list[str],
        typer.Option(
            "--twin",
            help="A twin: radio map (.json), recorded flight (.csv, fitted on the fly) or "
            "scenario/preset (its model). Repeat for several.",
        ),
    ],
    policies: Annotated[
        str, typer.Option("--policies", help="Comma-separated fixed-path policies.")
    ] = "greedy,hgad",
    calibration: Annotated[
        list[Path] | None,
        typer.Option(
            "--calibration",
            help="A flight (.csv) the twins were calibrated on: the log-distance reference is "
            "fitted on these. Repeat for several.",
        ),
    ] = None,
    download_log: Annotated[
        Path | None,
        typer.Option(
            "--download-log",
            help="The real flight's download log: its serving decisions are the same "
            "decisions of the same-decisions error.",
        ),
    ] = None,
    block: Annotated[
        int | None,
        typer.Option(
            "--block", min=1, help="Consecutive samples per bootstrap block [default: 10]."
        ),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the bootstrap.")] = 0,
    json_out: Annotated[bool, typer.Option("--json", help="Print the result as JSON.")] = False,
    out: Annotated[
        Path | None, typer.Option("--out", help="Folder for the figures and report.html.")
    ] = None,
    pdf: Annotated[bool, typer.Option("--pdf/--no-pdf", help="Also write vector PDFs.")] = True,
    force: Annotated[
        bool, typer.Option("--force", help="Write into --out even if it holds something else.")
    ] = False,
) -> None:
    """Which twin to trust on a real flight: SNR per tower and reference rows, each policy's
    same-decisions error, decision regret and own error (90% CIs), and a ranking."""
    from skymule.cli.folders import guard_sim2real
    from skymule.cli.missions import _working
    from skymule.metrics.sim2real import Bootstrap
    from skymule.tasks.sim2real import (
        finite,
        policy_table,
        ranking_table,
        sim2real,
        snr_table,
        write_sim2real,
    )

    check_seed(seed)
    if out is not None:
        guard_sim2real(out, force)
    names = [p.strip() for p in policies.split(",") if p.strip()]
    boot = Bootstrap(seed=seed) if block is None else Bootstrap(block=block, seed=seed)
    with _working("flying the real path under each twin"):
        result = sim2real(
            scenario, real_trace, twin, names, calibration=calibration or (),
            download_log=download_log, boot=boot,
        )  # fmt: skip
    if out is not None:
        write_sim2real(result, out)
        report_path = _report(out, pdf)
    document = finite(result.to_json())
    if json_out:
        output.print_json(document)
        return
    level = f"{100 * boot.level:.0f}% CI: block bootstrap, {boot.block} samples a block"
    columns, rows = snr_table(document)
    title = f"{real_trace.name}: SNR, predicted - measured, value [{level}]; ref: references"
    print_table(output.console, title, rows, columns)
    columns, rows = policy_table(document)
    title = (
        f"{real_trace.name}: policy Mbit, [%] of the real side [{level}]; regret: the twin's "
        "decisions executed on the real trace"
    )
    print_table(output.console, title, rows, columns)
    columns, rows = ranking_table(document)
    print_table(output.console, "twins by decision regret (mean over the policies)", rows, columns)
    for note in result.notes:
        output.say(f"note: {note}")
    output.say(result.trust)
    if out is not None:
        output.say(f"wrote {out}/sim2real.json, {out}/sim2real_snr.csv, {report_path}")

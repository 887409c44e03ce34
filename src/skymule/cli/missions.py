"""Commands that simulate: run, compare, bound, sweep, scenarios."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

import skymule.cli.output as output
from skymule.cli.folders import guard_bound, guard_compare, guard_run, guard_sweep
from skymule.cli.output import print_json
from skymule.cli.tables import fmt_mean_ci, print_table
from skymule.errors import SkymuleError, interrupt_exit_status
from skymule.trust import TRUST_HELP, trust_option

if TYPE_CHECKING:
    from skymule.scenario import Scenario
    from skymule.tasks.compare import Comparison

ScenarioArg = Annotated[str, typer.Argument(help="Scenario TOML path or preset name.")]
SetOption = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        help="Override a scenario key, e.g. --set sensors[2].buffer_mbit=900 "
        "--set policy.params.max_hover_s=30 (TOML values; repeatable).",
    ),
]
JsonOption = Annotated[
    bool, typer.Option("--json", help="Print a machine-readable summary (JSON) instead.")
]
ForceOption = Annotated[
    bool,
    typer.Option(
        "--force",
        help="Write into --out even if it holds another result (which is removed first; "
        "files skymule did not write are kept).",
    ),
]

TrustOption = Annotated[
    list[Path] | None,
    typer.Option("--trust-model", help=TRUST_HELP, callback=trust_option),
]
"""--trust-model PATH: for this command (:func:`skymule.cli.main` restores it) and its workers."""
GAP_COLUMNS = ("gap_to_bound_mbit", "gap_to_bound_frac")


def summary_columns() -> tuple[str, ...]:
    from skymule.metrics.summary import HEADLINE_METRICS

    return ("policy", *HEADLINE_METRICS)


def load(scenario: str, overrides: list[str] | None, policies: list[str] | None = None) -> Scenario:
    """The scenario with ``--set`` applied; ``policies``: those the command runs instead of the
    file's own (``[policy.params]`` may hold any of their parameters)."""
    from skymule.scenario import load_scenario

    return load_scenario(scenario, overrides or (), policies=policies)


def announce_imports(names: list[str], source: str | Path) -> None:
    """One stderr line per plug-in module that policies named in a file make the command
    import (names typed on the command line need no notice)."""
    from skymule.policies.registry import plugin_module

    for name in dict.fromkeys(names):
        module = plugin_module(name)
        if module is not None:
            print(
                f"skymule: importing module {module} for policy {name!r} (named in {source})",
                file=sys.stderr,
            )


def per_sensor_rows(summary: dict[str, Any]) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = [
        {"sensor": name, "buffer_mbit": buffer, "downloaded_mbit": down}
        for (name, buffer), down in zip(
            summary["per_sensor_buffer_mbit"].items(),
            summary["per_sensor_downloaded_mbit"].values(),
            strict=True,
        )
    ]
    rows.append(
        {
            "sensor": "total",
            "buffer_mbit": summary["total_buffer_mbit"],
            "downloaded_mbit": summary["total_downloaded_mbit"],
        }
    )
    return rows


def run(
    scenario: ScenarioArg,
    out: Annotated[Path | None, typer.Option("--out", help="Run folder to write.")] = None,
    policy: Annotated[str | None, typer.Option("--policy", help="Override the policy.")] = None,
    overrides: SetOption = None,
    json_out: JsonOption = False,
    force: ForceOption = False,
    trust_model: TrustOption = None,
) -> None:
    """Run one mission and print its summary."""
    from skymule.tasks.simulate import simulate

    spec = load(scenario, overrides, None if policy is None else [policy])
    if spec.uavs:  # several UAVs (docs/fleet.md)
        from skymule.cli.fleet import run_fleet_command

        if out is not None:
            guard_run(out, spec.name, policy or spec.policy.name, force)
        if policy is None:
            announce_imports(fleet_policy_names(spec), scenario)
        return run_fleet_command(spec, policy, out, json_out)
    if policy is not None:
        from skymule.scenario import plugin_default_overrides

        warn(plugin_default_overrides(spec.policy.params, [policy], spec.policy.name))
        spec = spec.with_policy(policy)
    if out is not None:
        guard_run(out, spec.name, spec.policy.name, force)
    if policy is None:
        announce_imports([spec.policy.name], scenario)
    result = simulate(spec)
    if out is not None:
        result.write(out)
    if json_out:
        print_json(result.summary)
        return
    title = f"{result.summary['scenario']} - {result.summary['policy']}"
    print_table(
        output.console, title, per_sensor_rows(result.summary),
        ("sensor", "buffer_mbit", "downloaded_mbit"),
    )  # fmt: skip
    print_table(output.console, "summary", [result.summary], summary_columns())
    testbed = testbed_line(spec, result)
    if testbed:
        output.say(testbed)
    if out is not None:
        output.say(f"wrote {out}/summary.json, slots.csv, scenario.json")


def testbed_line(spec: Scenario, result: Any) -> str | None:
    """The AADM score at the testbed's poll cadence (``[aadm] poll_interval_s``; the table's
    AADM counts 1 s a poll), one line; None when a slot is not the controller's 1-s poll."""
    from skymule.aadm.score import AADM_POLL_S, scenario_prediction

    mission = result.mission
    if abs(mission.slot_s - AADM_POLL_S) > 1e-9:
        return None
    parts = scenario_prediction(
        spec, result.log.downloaded_bit, float(mission.buffers_bit.sum()), mission.score_window_s
    )
    jitter = float(parts["aadm_poll_jitter_s"])
    cadence = f"{float(parts['aadm_poll_interval_s']):g}" + (f"±{jitter:g}" if jitter else "")
    return (  # short: the line fits a 60-column terminal
        f"testbed ({cadence} s/poll): t1 {float(parts['aadm_t1_s']):.1f} s, "
        f"AADM {float(parts['aadm_score']):.1f}"
    )


def fleet_policy_names(spec: Scenario) -> list[str]:
    """The policies a fleet scenario's UAVs fly: each UAV's own, else the scenario's."""
    return [(uav.policy or spec.policy).name for uav in spec.uavs or ()]


def warn(lines: Sequence[str]) -> None:
    """Print each line as a warning on stderr (the result is still written and printed)."""
    for line in lines:
        print(f"skymule: warning: {line}", file=sys.stderr)


def _names(text: str) -> list[str]:
    return [p.strip() for p in text.split(",") if p.strip()]


def compare(
    scenario: ScenarioArg,
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
    overrides: SetOption = None,
    json_out: JsonOption = False,
    force: ForceOption = False,
    trust_model: TrustOption = None,
) -> None:
    """Run one scenario under several policies on identical signal draws."""
    from skymule.policies import check_policies
    from skymule.scenario import plugin_default_overrides
    from skymule.tasks.compare import (
        compare_policies,
        compare_sources,
        parse_sources,
        write_compare,
    )

    base = load(scenario, overrides, _names(policies))
    if sources is None and base.uavs:  # several UAVs (docs/fleet.md)
        from skymule.cli.fleet import check_policy_names, compare_fleet_command

        fleet_names = _names(policies)
        check_policy_names(fleet_names, policies)
        if out is not None:
            guard_compare(out, base.name, fleet_names, force)
        return compare_fleet_command(base, fleet_names, out, json_out)
    names = check_policies(_names(policies))
    source_specs = parse_sources(sources) if sources is not None else None
    if out is not None:
        guard_compare(out, base.name, names, force, source_specs)
    warn(plugin_default_overrides(base.policy.params, names, base.policy.name))
    if source_specs is None:
        comparison = compare_policies(base, names)
    else:
        comparison = compare_sources(base, source_specs, names)
    written = write_compare(comparison, out) if out is not None else []
    for source, upper in comparison.bounds.items():
        where = f"{source}: " if source is not None else ""
        warn([f"{where}upper bound: {w}" for w in upper.warnings] if upper else [])
    if json_out:
        print_json(_comparison_json(comparison))
        return
    columns = ("source",) if comparison.by_source else ()
    title = "signal sources" if comparison.by_source else f"{base.name}: comparison"
    print_table(
        output.console,
        title,
        comparison.rows_with_bounds(),
        (*columns, *summary_columns(), *GAP_COLUMNS),
    )
    for source, note in comparison.notes.items():
        where = f"{source}: " if source is not None else ""
        output.say(f"{where}no upper bound: {note}")
    if out is not None:
        names_written = ", ".join(str(p) for p in written)
        output.say(f"wrote {names_written} and one folder per run")


def _comparison_json(comparison: Comparison) -> dict[str, Any]:
    bounds = {
        str(source) if source is not None else "scenario": (
            None if upper is None else upper.to_json_dict()
        )
        for source, upper in comparison.bounds.items()
    }
    return {
        "scenario": comparison.scenario.name,
        "runs": comparison.rows(),
        "bounds": bounds,
        "notes": {str(k): v for k, v in comparison.notes.items()},
    }


def bound_rows(record: dict[str, Any]) -> list[dict[str, Any]]:
    """The bound's quantities as table rows (its warnings go to stderr, one line each)."""
    shown = {k: v for k, v in record.items() if v is not None and k != "warnings"}
    return [{"quantity": k, "value": v} for k, v in shown.items()]


def bound(
    scenario: ScenarioArg,
    out: Annotated[Path | None, typer.Option("--out", help="Folder for bound.json.")] = None,
    overrides: SetOption = None,
    json_out: JsonOption = False,
    force: ForceOption = False,
) -> None:
    """Upper bound on the data any policy can download in a scenario (LP/MILP, HiGHS)."""
    from skymule.tasks.compare import scenario_bound, write_bound

    spec = load(scenario, overrides)
    if out is not None:
        guard_bound(out, spec.name, force)
    with _working("solving the bound"):
        upper = scenario_bound(spec)
    record = upper.to_json_dict()
    path = write_bound(out, upper) if out is not None else None
    warn(upper.warnings)
    if json_out:
        print_json(record)
        return
    print_table(
        output.console,
        f"{record['scenario']}: upper bound",
        bound_rows(record),
        ("quantity", "value"),
    )
    if path is not None:
        output.say(f"wrote {path}")


class _working:
    """A spinner with elapsed time on stderr while ``what`` runs; nothing when piped."""

    def __init__(self, what: str) -> None:
        self.what = what
        self.status: Any = None

    def __enter__(self) -> None:
        if sys.stderr.isatty():
            from rich.console import Console

            self.status = Console(stderr=True).status(f"{self.what}...")
            self.status.__enter__()

    def __exit__(self, *exc: object) -> None:
        if self.status is not None:
            self.status.__exit__(None, None, None)


def scenarios(
    show: Annotated[
        str | None, typer.Option("--show", help="Print this preset's TOML (with comments).")
    ] = None,
) -> None:
    """List the built-in scenario presets, or print one with --show NAME."""
    from skymule.scenario import load_scenario, presets

    registry = presets()
    if show is not None:
        print(registry.get(show), end="")
        return
    rows = []
    for name in registry.names():
        spec = load_scenario(name)
        rows.append(
            {
                "name": name,
                "mode": spec.trajectory.mode,
                "source": spec.signal.source,
                "duration [s]": spec.mission.duration_s,
                "sensors": ", ".join(f"{s.name}:{s.buffer_mbit:g}" for s in spec.sensors),
            }
        )
    columns = ("name", "mode", "source", "duration [s]", "sensors")
    print_table(output.console, "built-in scenarios", rows, columns)


SWEEP_METRICS = ("total_downloaded_mbit", "completion", "handovers", "hover_time_s", "distance_m")


def sweep(
    sweep_file: Annotated[Path, typer.Argument(help="Sweep TOML (base scenario + axes).")],
    out: Annotated[Path, typer.Option("--out", help="Sweep folder (resumed if it exists).")],
    executor: Annotated[
        str,
        typer.Option(
            "--executor",
            help="auto (this process for a small sweep, else a process pool: by estimated "
            "work), inprocess, process, dask-local or dask.",
        ),
    ] = "auto",
    workers: Annotated[
        int | None, typer.Option("--workers", help="Workers (default: all cores).")
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Dask scheduler tcp://HOST:PORT.")
    ] = None,
    chunk_size: Annotated[int, typer.Option("--chunk-size", help="Missions per chunk.")] = 500,
    quiet: Annotated[bool, typer.Option("--quiet", help="No progress bar.")] = False,
    overrides: SetOption = None,
    force: ForceOption = False,
    trust_model: TrustOption = None,
) -> None:
    """Run many missions (resumable); results.parquet and summary.csv in --out."""
    from skymule.experiments.run import run_sweep
    from skymule.experiments.sweep import load_sweep
    from skymule.policies import check_policies

    spec = load_sweep(sweep_file)
    if overrides:
        spec = _sweep_with_overrides(spec, overrides)
    check_policies(spec.policy_names, f"{sweep_file}: policy.name")  # before any worker starts
    chosen = sweep_executor(executor, spec, workers, scheduler)
    guard_sweep(out, sweep_file, force)
    announce_imports(spec.policy_names, sweep_file)
    try:
        outcome = run_sweep(
            spec,
            out,
            executor=chosen,
            workers=workers,
            scheduler=scheduler,
            chunk_size=chunk_size,
            progress=not quiet and sys.stderr.isatty(),
        )
    except KeyboardInterrupt as interrupt:
        again = ["skymule", "sweep", str(sweep_file), "--out", str(out)]
        again += ["--executor", executor] if executor != "auto" else []
        again += ["--workers", str(workers)] if workers is not None else []
        again += ["--scheduler", scheduler] if scheduler else []
        again += ["--chunk-size", str(chunk_size)] if chunk_size != 500 else []
        again += [f"--set={o}" for o in overrides or []]
        again += [f"--trust-model={p}" for p in trust_model or []]
        _sweep_interrupted(out, spec, again, interrupt_exit_status(interrupt))
    levels = [c for c in spec.level_columns if c in outcome.summary.columns]
    rows = [
        {
            "policy": row["policy"],
            **{c: row[c] for c in levels},
            "missions": row["missions"],
            **{m: fmt_mean_ci(row[f"{m}_mean"], row[f"{m}_ci95"]) for m in SWEEP_METRICS},
        }
        for row in outcome.summary.to_dict("records")
    ]
    title = f"{sweep_file.name}: {outcome.n_missions} missions (mean ± 95% CI)"
    print_table(output.console, title, rows, ("policy", *levels, "missions", *SWEEP_METRICS))
    how = f" ({chosen}, chosen by estimated work)" if executor == "auto" else ""
    output.say(
        f"ran {outcome.n_run} of {outcome.n_missions} missions in {outcome.seconds:.1f} s"
        f"{how}; wrote {out}/results.parquet and {out}/summary.csv"
    )


def sweep_executor(executor: str, spec: Any, workers: int | None, scheduler: str | None) -> str:
    """The executor ``--executor`` names; for ``auto``, ``dask`` with a ``--scheduler``, else
    the local one that finishes sooner (:func:`skymule.experiments.workload.choose_executor`)."""
    from skymule.experiments.executors import EXECUTORS, default_workers

    if executor == "auto":
        from skymule.experiments.workload import choose_executor

        if scheduler is not None:
            return "dask"
        return choose_executor(spec, workers or default_workers())
    if executor not in EXECUTORS:
        from skymule.registry import unknown_name_message

        choices = ["auto", *EXECUTORS.names()]
        raise SkymuleError(unknown_name_message("--executor", executor, choices))
    return executor


def _sweep_with_overrides(spec: Any, overrides: list[str]) -> Any:
    """The sweep with ``--set`` applied to its base scenario (validated like a file)."""
    import hashlib
    from dataclasses import replace

    from skymule.overrides import apply_override
    from skymule.scenario import scenario_from_dict

    data = spec.base.to_toml_dict()
    for override in overrides:
        data = apply_override(data, override)
    source = f"{spec.source} (--set)"
    base = scenario_from_dict(data, source, Path(spec.base.base_dir), policies=spec.policy_names)
    # the folder's sweep identity covers the overrides: resuming needs the same --set
    digest = hashlib.sha256("\0".join([spec.digest, *overrides]).encode()).hexdigest()
    return replace(spec, base=base, digest=digest)


def _sweep_interrupted(out: Path, spec: Any, again: list[str], status: int) -> None:
    """Ctrl-C or SIGTERM: say what was kept and the command that resumes; exit with
    ``status`` (130 or 143)."""
    import shlex

    from skymule.experiments import store

    try:
        kept, total = store.scan(out).count, len(spec)
        what = f"kept {kept} of {total} missions in {out / store.PARTS}"
    except Exception:  # a half-written part must not hide the resume hint
        what = f"finished chunks are kept in {out}"
    command = " ".join(shlex.quote(a) for a in again)
    print(f"skymule: interrupted; {what}. Resume with: {command}", file=sys.stderr)
    raise SystemExit(status)

"""``skymule resilience``: degradation curves of every policy over a fault's intensity."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

import skymule.cli.output as output
from skymule.cli.missions import ScenarioArg, SetOption, TrustOption, _names, load
from skymule.cli.tables import print_table
from skymule.errors import SkymuleError
from skymule.io import atomic

COLUMNS = (
    "policy", "level", "missions", "mbit_mean", "mbit_ci95", "aadm_score_mean", "bound_mbit_mean"
)  # fmt: skip


def resilience(
    scenario: ScenarioArg,
    fault: Annotated[
        str,
        typer.Option(
            "--fault",
            help="Fault kind: outage, gilbert-elliott, snr-error, missed-polls, gps-error, wind.",
        ),
    ],
    levels: Annotated[
        str,
        typer.Option(
            "--levels",
            help="Comma-separated intensities of --fault, e.g. 0,60,120: outage mean length "
            "[s], gilbert-elliott share of lost slots [0-1), snr-error std [dB], missed-polls "
            "probability [0-1), gps-error std [m], wind speed [m/s].",
        ),
    ],
    out: Annotated[Path, typer.Option("--out", help="Folder for resilience.csv/.png.")],
    policies: Annotated[
        str, typer.Option("--policies", help="Comma-separated policy names.")
    ] = "greedy,hgad,hgad-robust",
    missions: Annotated[
        int, typer.Option("--missions", help="Paired missions per level (seeds seed..seed+N-1).")
    ] = 20,
    overrides: SetOption = None,
    trust_model: TrustOption = None,
) -> None:
    """Every policy over increasing fault intensity, paired draws: Mbit (mean, 95 % CI)."""
    from skymule.policies import check_policies
    from skymule.report.resilience import plot_resilience
    from skymule.tasks.resilience import LEVELS, parse_levels, run_study, table

    values = parse_levels(levels, fault)
    names = check_policies(_names(policies))
    if missions < 1:
        raise SkymuleError(f"--missions = {missions}; allowed: an integer >= 1")
    if out.exists() and not out.is_dir():
        raise SkymuleError(f"--out {out}: exists and is not a folder")
    base = load(scenario, overrides, names)
    if base.uavs:
        raise SkymuleError("resilience runs one UAV; this scenario has [[uavs]]")
    frame = table(run_study(base, fault, values, names, missions))
    out.mkdir(parents=True, exist_ok=True)
    atomic.write_with(out / "resilience.csv", lambda tmp: frame.to_csv(tmp, index=False))
    from skymule.report.style import scenario_description

    words = scenario_description(base.to_toml_dict(), {"mission_time_s": base.mission.duration_s})
    plot_resilience(frame, LEVELS[fault][0], out / "resilience.png", f"{words}: {fault}")
    rows = [{str(k): v for k, v in row.items()} for row in frame.to_dict("records")]
    print_table(output.console, f"{base.name}: {fault}", rows, COLUMNS)
    output.say(f"wrote {out}/resilience.csv, resilience.png")

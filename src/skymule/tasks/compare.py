"""Compare policies (or signal sources) on identical draws, and write compare folders.

The Python API behind ``skymule compare``, ``skymule compare --sources`` and
``skymule analyze``::

    from skymule.tasks.compare import compare_policies, write_compare
    from skymule.scenario import load_scenario

    comparison = compare_policies(load_scenario("paper-sim-fixed"), ["greedy", "hgad"])
    comparison.rows()          # one dict per run: the summary metrics + gap to the bound
    write_compare(comparison, Path("cmp"))   # cmp/comparison.csv, cmp/<policy>/, cmp/bound.json

Every policy of one signal source runs on one built :class:`~skymule.world.Mission`, so they
see the same SNR draws (shadowing, fading). The mission's upper bound
(:mod:`skymule.bounds`) is added as ``upper_bound_mbit`` and ``gap_to_bound_*`` columns when
the scenario has one; when it has none, :attr:`Comparison.notes` says why.

A source spec is a path-loss model name (``fspl``, ``log-distance``, ``al-hourani``, ...: the
scenario with ``[radio] model`` set to it and ``[signal] source = "model"``), ``radiomap:FILE``
(a fitted map) or ``scenario`` (the scenario as written). Everything else (sensors, path, link
budget, shadowing/fading settings, seed) stays the same.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar, cast

from skymule.errors import SkymuleError
from skymule.io import atomic
from skymule.metrics.summary import per_sensor_column
from skymule.policies import check_policies
from skymule.radio.pathloss import PATHLOSS_MODELS
from skymule.registry import did_you_mean
from skymule.scenario import Scenario
from skymule.tasks.simulate import RunResult, simulate
from skymule.world import Mission, build_mission

if TYPE_CHECKING:
    from skymule.bounds.result import MissionBound

GAP_COLUMNS = ("gap_to_bound_mbit", "gap_to_bound_frac")
"""bound - downloaded [Mbit] and that gap as a fraction of the bound."""

COMPARISON_CSV = "comparison.csv"
BOUND_JSON = "bound.json"
SCENARIO_SOURCE = "scenario"


@dataclass(frozen=True)
class CompareRun:
    """One run of a comparison: its source spec (None: the scenario's own), policy, result."""

    source: str | None
    policy: str
    result: RunResult


@dataclass(frozen=True)
class Comparison:
    """Runs on identical draws, with each source's upper bound (or why there is none)."""

    scenario: Scenario
    runs: tuple[CompareRun, ...]
    bounds: dict[str | None, MissionBound | None] = field(default_factory=dict)
    notes: dict[str | None, str] = field(default_factory=dict)

    @property
    def by_source(self) -> bool:
        return any(run.source is not None for run in self.runs)

    def rows(self) -> list[dict[str, Any]]:
        """comparison.csv rows: flat summary + bound and gap columns (when there is a bound)."""
        rows = []
        for run in self.runs:
            row = comparison_row(run.result.summary)
            row = with_gap(row, self.bounds.get(run.source))
            rows.append({"source": run.source, **row} if self.by_source else row)
        return rows

    def with_summaries(self, extra: Callable[[CompareRun], dict[str, Any]]) -> Comparison:
        """This comparison with ``extra(run)`` merged into every run's summary (e.g. the
        AADM score parts ``analyze`` computes from the recorded flight's share slot)."""
        runs = tuple(
            replace(run, result=replace(run.result, summary={**run.result.summary, **extra(run)}))
            for run in self.runs
        )
        return replace(self, runs=runs)

    def rows_with_bounds(self) -> list[dict[str, Any]]:
        """:meth:`rows` with a ``bound`` row after each source's last policy (for printing)."""
        shown: list[dict[str, Any]] = []
        rows = self.rows()
        for index, (row, run) in enumerate(zip(rows, self.runs, strict=True)):
            shown.append(row)
            last = index + 1 == len(self.runs) or self.runs[index + 1].source != run.source
            upper = self.bounds.get(run.source)
            if last and upper is not None:
                extra = {"source": run.source} if self.by_source else {}
                shown.append(bound_row(upper, **extra))
        return shown


def comparison_row(summary: dict[str, Any]) -> dict[str, Any]:
    """A comparison.csv row: the summary's scalars + ``per_sensor_downloaded_mbit.<sensor>``
    columns (the names of a sweep's ``results.parquet``: :func:`per_sensor_column`)."""
    row = {k: v for k, v in summary.items() if not isinstance(v, dict | list)}
    for name, value in summary.get("per_sensor_downloaded_mbit", {}).items():
        row[per_sensor_column("per_sensor_downloaded_mbit", name)] = value
    return row


def mission_bound_or_note(mission: Mission) -> tuple[MissionBound | None, str | None]:
    """(the mission's upper bound, None), or (None, why this mission has none)."""
    from skymule.bounds.mission import mission_bound
    from skymule.bounds.result import BoundError

    try:
        return mission_bound(mission), None
    except BoundError as exc:
        return None, str(exc)


def scenario_bound(scenario: Scenario) -> MissionBound:
    """The upper bound on what any policy can download in ``scenario`` (one-line error if none);
    with ``[[uavs]]``, the K-UAV bound (``docs/fleet.md``). In Mbit:
    ``scenario_bound(s).upper_bound_mbit`` (``upper_bound_bit`` inside)."""
    if scenario.uavs:
        from skymule.bounds.fleet import fleet_bound
        from skymule.sim.fleet import build_fleet

        return fleet_bound(build_fleet(scenario))
    from skymule.bounds.mission import mission_bound

    return mission_bound(build_mission(scenario))


def with_gap(row: dict[str, Any], upper: MissionBound | None) -> dict[str, Any]:
    """``row`` plus upper_bound_mbit and the gap columns (unchanged without a bound)."""
    if upper is None:
        return row
    bound_mbit = upper.upper_bound_mbit
    gap = bound_mbit - row["total_downloaded_mbit"]
    frac = gap / bound_mbit if bound_mbit > 0 else 0.0
    return {**row, "upper_bound_mbit": bound_mbit, GAP_COLUMNS[0]: gap, GAP_COLUMNS[1]: frac}


def bound_row(upper: MissionBound, **extra: object) -> dict[str, Any]:
    """The ``bound`` row of a printed comparison: only the total is filled."""
    return {
        **extra,
        "policy": "bound",
        "total_downloaded_mbit": upper.upper_bound_mbit,
    }


def write_bound(folder: Path, upper: MissionBound) -> Path:
    """Write ``folder/bound.json`` (Mbit) and return its path."""
    folder.mkdir(parents=True, exist_ok=True)
    return atomic.write_text(folder / BOUND_JSON, json.dumps(upper.to_json_dict(), indent=2) + "\n")


def _run_all(
    scenario: Scenario, policies: Sequence[str], source: str | None, mission: Mission | None
) -> list[CompareRun]:
    shared = build_mission(scenario) if mission is None else mission
    variants = scenario.with_policies(policies)  # each policy gets its own parameters
    results = [simulate(variant, mission=shared) for variant in variants]
    return [
        CompareRun(source, name, result)
        for name, result in zip(policies, distinct_labels(results, policies), strict=True)
    ]


_Result = TypeVar("_Result")


def distinct_labels(results: Sequence[_Result], asked: Sequence[str]) -> list[_Result]:
    """``results`` (frozen dataclasses with a ``summary`` dict: one UAV's or a fleet's) with
    each summary's ``policy`` (the policy's own ``name``) kept when it is one policy's, and
    replaced by the name as asked when several policies share it: two plug-ins whose classes
    share a ``name`` (``mostbits:MostBits,mostbits:MostBitsBatched``) are two rows and two
    folders, not two identical ones."""
    summaries = [cast(Any, r).summary for r in results]
    labels = [str(s.get("policy", a)) for s, a in zip(summaries, asked, strict=True)]
    shared = {label for label in labels if labels.count(label) > 1}
    return [
        cast(_Result, replace(cast(Any, r), summary={**s, "policy": a}))
        if label in shared and a != label
        else r
        for r, s, a, label in zip(results, summaries, asked, labels, strict=True)
    ]


def compare_policies(
    scenario: Scenario,
    policies: Sequence[str],
    *,
    bound: bool = True,
    mission: Mission | None = None,
) -> Comparison:
    """Run ``scenario`` under every policy on one mission (identical draws).

    ``bound=False`` skips the upper bound; ``mission`` reuses a mission built earlier.
    """
    names = check_policies(list(policies))
    check_folders(names)
    shared = build_mission(scenario) if mission is None else mission
    runs = _run_all(scenario, names, None, shared)
    if not bound:
        return Comparison(scenario, tuple(runs))
    upper, note = mission_bound_or_note(shared)
    return Comparison(scenario, tuple(runs), {None: upper}, {} if note is None else {None: note})


def source_variant(base: Scenario, spec: str) -> Scenario:
    """The scenario ``base`` with its signal source replaced as ``spec`` says."""
    spec = spec.strip()
    signal = base.signal
    if spec == SCENARIO_SOURCE:
        return base
    if spec.startswith("radiomap:") and spec[len("radiomap:") :]:
        path = str(Path(spec[len("radiomap:") :]).resolve())
        update = {"source": "radiomap", "map": path, "traces": None, "trace": None}
        return base.model_copy(update={"signal": signal.model_copy(update=update)})
    if spec in PATHLOSS_MODELS:
        radio = type(base.radio).model_validate({**base.radio.model_dump(), "model": spec})
        update = {"source": "model", "map": None, "traces": None, "trace": None}
        return base.model_copy(update={"radio": radio, "signal": signal.model_copy(update=update)})
    choices = [*PATHLOSS_MODELS.names(), SCENARIO_SOURCE]
    raise SkymuleError(
        f"--sources: unknown source {spec!r}; allowed: {', '.join(PATHLOSS_MODELS.names())}, "
        f"radiomap:FILE.json or scenario{did_you_mean(spec, choices)}"
    )


def parse_sources(text: str) -> list[str]:
    """``--sources`` text -> source specs (one-line error when empty)."""
    specs = [s.strip() for s in text.split(",") if s.strip()]
    if not specs:
        raise SkymuleError("--sources is empty; give e.g. fspl,log-distance,radiomap:map.json")
    return specs


def safe_folder_name(text: str, fallback: str, keep: str = "") -> str:
    """One file-system-safe path component for user text (a policy or source spec): no
    separator, never ``.``/``..``, so the folder stays inside ``--out`` whatever was asked
    (``learned:../../../w.npz`` -> ``learned_.._.._.._w.npz``); ``keep``: other characters
    left as they are."""
    name = re.sub(rf"[^A-Za-z0-9._{re.escape(keep)}-]+", "_", text.strip()).strip("_")
    return name if name.strip(".") else fallback


def source_folder(spec: str) -> str:
    """A file-system-safe folder name for a source spec."""
    return safe_folder_name(spec, "source")


def policy_folder(policy: str) -> str:
    """A file-system-safe folder name for a policy as asked (``mostbits:MostBits`` stays,
    ``learned:dir/w.npz`` -> ``learned:dir_w.npz``)."""
    return safe_folder_name(policy, "policy", keep=":")


def check_folders(policies: Sequence[str]) -> None:
    """Refuse two different policy names that would share one run folder (one line)."""
    seen: dict[str, str] = {}
    for name in policies:
        folder = policy_folder(name)
        if seen.setdefault(folder, name) != name:
            raise SkymuleError(
                f"--policies: {seen[folder]!r} and {name!r} would both be written to the "
                f"folder {folder!r}; rename one of the files"
            )


def compare_sources(
    base: Scenario, sources: Sequence[str], policies: Sequence[str], *, bound: bool = True
) -> Comparison:
    """Every source x policy; the policies of one source share one mission."""
    names = check_policies(list(policies))
    check_folders(names)
    variants = [(spec, source_variant(base, spec)) for spec in sources]  # validate all first
    runs: list[CompareRun] = []
    bounds: dict[str | None, MissionBound | None] = {}
    notes: dict[str | None, str] = {}
    for spec, scenario in variants:
        mission = build_mission(scenario)
        runs.extend(_run_all(scenario, names, spec, mission))
        if bound:
            bounds[spec], note = mission_bound_or_note(mission)
            if note is not None:
                notes[spec] = note
    return Comparison(base, tuple(runs), bounds, notes)


def run_folder(out: Path, run: CompareRun) -> Path:
    """Where a run of a comparison is written inside the compare folder ``out``."""
    if run.source is None:
        return out / policy_folder(run.policy)
    return out / source_folder(run.source) / policy_folder(run.policy)


def write_compare(
    comparison: Comparison, out: Path, extra_rows: Sequence[dict[str, Any]] = ()
) -> list[Path]:
    """Write the compare folder: one run folder per run, bound.json, and comparison.csv last
    (the index: a folder is a complete comparison once it has it,
    :func:`skymule.io.runs.check_complete_comparison`).

    ``extra_rows`` are appended to comparison.csv (e.g. ``analyze``'s recorded ``flight``).
    With sources, also ``snr_cdf_by_source.png`` (SNR CDF of the first policy per source).
    Returns the files written at the top of ``out``.
    """
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    (out / COMPARISON_CSV).unlink(missing_ok=True)  # a rewrite cut short is incomplete too
    for run in comparison.runs:
        run.result.write(run_folder(out, run))
    written = []
    if not comparison.by_source:
        upper = comparison.bounds.get(None)
        if upper is not None:
            written.append(write_bound(out, upper))
    else:
        written.append(_snr_cdf_figure(comparison, out))
    # the index last: a folder without it is an interrupted compare, which readers refuse
    table = pd.DataFrame([*comparison.rows(), *extra_rows])
    index = atomic.write_with(out / COMPARISON_CSV, lambda tmp: table.to_csv(tmp, index=False))
    return [index, *written]


def _snr_cdf_figure(comparison: Comparison, out: Path) -> Path:
    from skymule.io.runs import read_run
    from skymule.report.channel import plot_snr_cdf_by_source

    first_policy = comparison.runs[0].policy
    panels = [
        (str(run.source), read_run(run_folder(out, run))[1])
        for run in comparison.runs
        if run.policy == first_policy
    ]
    figure = out / "snr_cdf_by_source.png"
    plot_snr_cdf_by_source(panels, figure, f"SNR CDF by signal source ({first_policy})")
    return figure

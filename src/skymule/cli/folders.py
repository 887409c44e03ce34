"""Output folders: never silently overwrite or mix one kind of result with another.

A non-empty ``--out`` is written to only when it already holds the same thing (a run of the
same policy and scenario, a comparison of the same scenario, policies and signal sources, a
bound of the same scenario, a sweep); anything else is one line and exit 2 unless ``--force``,
which first removes what skymule wrote there (:func:`clear_results`; other files stay), so a
folder never holds two results at once. Which sweep a sweep folder holds is the store's
business (``sweep.json``, see :mod:`skymule.experiments.store`): it refuses another sweep
file, in one line.
"""

from __future__ import annotations

import csv
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from skymule.errors import SkymuleError
from skymule.io.textfiles import parse_json

SWEEP_FILES = ("sweep.json", "results", "results.parquet", "summary.csv", ".lock", ".lock.holder")
"""What a sweep folder holds (``skymule.experiments.store``)."""

SIM2REAL_FILE = "sim2real.json"
"""What marks a ``skymule sim2real --out`` folder (``skymule.tasks.sim2real``)."""


@dataclass(frozen=True)
class Holds:
    """What an output folder holds: its kind and, where known, scenario and policies."""

    kind: str  # "empty", "run", "compare", "bound", "sweep", "sim2real" or "other"
    scenario: str | None = None
    policies: tuple[str, ...] = ()
    sources: tuple[str, ...] = ()  # a comparison of signal sources (``compare --sources``)

    def describe(self) -> str:
        if self.kind == "run":
            return f"a run of policy {self.policies[0]!r} on scenario {self.scenario!r}"
        if self.kind == "compare":
            under = f" under sources {', '.join(self.sources)}" if self.sources else ""
            names = ", ".join(self.policies)
            return f"a comparison of {names}{under} on scenario {self.scenario!r}"
        if self.kind == "bound":
            return f"the bound of scenario {self.scenario!r}"
        if self.kind == "sweep":
            return "a sweep"
        if self.kind == "sim2real":
            return "a sim2real comparison"
        return "other files"


def _read_json(path: Path) -> dict[str, Any]:
    try:
        data = parse_json(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _distinct(values: list[str]) -> tuple[str, ...]:
    return tuple(dict.fromkeys(v for v in values if v))


def _comparison(path: Path) -> Holds:
    """What a comparison.csv describes: scenario, policies and (``--sources``) sources, each
    name once (a source comparison has one row per source and policy)."""
    try:
        with path.open(newline="") as handle:
            rows = list(csv.DictReader(handle))
    except (OSError, csv.Error, UnicodeDecodeError):
        return Holds("compare")
    scenarios = {r.get("scenario") for r in rows}
    scenario = scenarios.pop() if len(scenarios) == 1 else None
    policies = _distinct([r.get("policy") or "" for r in rows])
    return Holds("compare", scenario, policies, _distinct([r.get("source") or "" for r in rows]))


def inspect_folder(out: Path) -> Holds:
    """What ``out`` holds (``empty`` when missing or empty)."""
    if not out.exists() or (out.is_dir() and not any(out.iterdir())):
        return Holds("empty")
    if not out.is_dir():
        return Holds("other")
    if any((out / name).exists() for name in SWEEP_FILES):
        return Holds("sweep")
    if (out / SIM2REAL_FILE).exists():
        return Holds("sim2real")
    if (out / "comparison.csv").exists():
        return _comparison(out / "comparison.csv")
    if (out / "summary.json").exists():
        summary = _read_json(out / "summary.json")
        return Holds("run", summary.get("scenario"), (str(summary.get("policy")),))
    if (out / "bound.json").exists():
        return Holds("bound", _read_json(out / "bound.json").get("scenario"))
    return Holds("other")


def _refuse(out: Path, holds: Holds, wanted: str) -> SkymuleError:
    return SkymuleError(
        f"--out {out}: holds {holds.describe()}, not {wanted}; "
        "choose another folder or add --force to write over it"
    )


RESULT_FILES = (
    "comparison.csv", "bound.json", "snr_cdf_by_source.png", "summary.json", "slots.csv",
    "scenario.json", "report.html", "figures",
)  # fmt: skip
"""What run, compare and bound commands (and ``report``) write at the top of a folder."""


def _is_results_folder(path: Path) -> bool:
    """A run folder, or a folder of run folders (one signal source of a comparison)."""
    if (path / "summary.json").is_file():
        return True
    inside = list(path.iterdir())
    return bool(inside) and all(p.is_dir() and (p / "summary.json").is_file() for p in inside)


def _remove(out: Path, names: tuple[str, ...]) -> None:
    """Delete ``out/name`` for each of ``names`` that exists (file or folder)."""
    for name in names:
        path = out / name
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()


def clear_results(out: Path) -> None:
    """Remove what skymule wrote in ``out`` (its result files, run and source folders); the
    user's other files stay. ``--force`` calls it, so a folder never mixes two results."""
    _remove(out, RESULT_FILES)
    for path in out.iterdir():
        if path.is_dir() and _is_results_folder(path):
            shutil.rmtree(path)


def _replace_or_refuse(out: Path, holds: Holds, wanted: Holds, force: bool) -> None:
    if not force:
        raise _refuse(out, holds, wanted.describe())
    if holds.kind in ("run", "compare", "bound"):  # "other": nothing of ours to remove
        clear_results(out)


def guard_run(out: Path, scenario: str, policy: str, force: bool) -> None:
    holds, wanted = inspect_folder(out), Holds("run", scenario, (policy,))
    if holds.kind == "empty" or holds == wanted:
        return
    _replace_or_refuse(out, holds, wanted, force)


def guard_compare(
    out: Path, scenario: str, policies: list[str], force: bool, sources: list[str] | None = None
) -> None:
    """Refuse (or, with ``force``, clear) a folder that holds anything but this comparison:
    the same scenario, policies and signal sources, in any order."""
    holds = inspect_folder(out)
    wanted = Holds("compare", scenario, _distinct(policies), _distinct(sources or []))
    if holds.kind == "empty":
        return
    same = holds.kind == "compare" and holds.scenario == scenario
    if same and (set(holds.policies), set(holds.sources)) == (
        set(wanted.policies),
        set(wanted.sources),
    ):
        return  # the same comparison again
    _replace_or_refuse(out, holds, wanted, force)


def guard_analysis(out: Path, force: bool) -> None:
    holds = inspect_folder(out)
    if holds.kind in ("empty", "compare"):
        return
    if not force:
        raise _refuse(out, holds, "a replay (compare folder)")
    if holds.kind in ("run", "bound"):
        clear_results(out)


def guard_bound(out: Path, scenario: str, force: bool) -> None:
    """A bound goes into an empty folder, its own, or a comparison of policies on the same
    scenario (whose bound.json it is); a source comparison has one bound per source."""
    holds = inspect_folder(out)
    if holds.kind == "empty":
        return
    if holds.kind in ("bound", "compare") and holds.scenario == scenario and not holds.sources:
        return
    _replace_or_refuse(out, holds, Holds("bound", scenario), force)


def guard_sim2real(out: Path, force: bool) -> None:
    """Refuse a folder that holds anything but a sim2real comparison (unless ``--force``)."""
    holds = inspect_folder(out)
    if force or holds.kind in ("empty", "sim2real"):
        return
    raise _refuse(out, holds, "a sim2real comparison")


def guard_sweep(out: Path, sweep_file: Path, force: bool) -> None:
    """Refuse a folder that holds anything but a sweep; with ``--force``, clear it first.

    A sweep folder of another sweep file is refused by the store itself (its ``sweep.json``),
    unless ``--force`` cleared it here.
    """
    holds = inspect_folder(out)
    if holds.kind == "empty":
        return
    if not force:
        if holds.kind != "sweep":
            raise _refuse(out, holds, f"a sweep of {sweep_file}")
        return
    if holds.kind == "sweep":
        _remove(out, SWEEP_FILES)
